/* iwdg.c - the independent watchdog: on its own ~40 kHz LSI clock, it resets the chip
 * unless the main loop feeds it. Once started it cannot be stopped. */
#include "hal_stm32f1.h"

/* LSI / 32 with reload 312: 250 ms at the nominal 40 kHz (167-333 ms over the LSI's
 * 30-60 kHz). The longest main-loop stall is a page erase, 40 ms at most. */
#define IWDG_PR_DIV32 3u
#define IWDG_RELOAD 312u

void hal_watchdog_start(struct hal *h)
{
    (void)h;
    REG_WRITE(IWDG->kr, IWDG_KEY_START); /* also starts the LSI */
    REG_WRITE(IWDG->kr, IWDG_KEY_ACCESS);
    REG_WRITE(IWDG->pr, IWDG_PR_DIV32);
    REG_WRITE(IWDG->rlr, IWDG_RELOAD);
    /* The new values cross into the LSI domain; bounded, an emulator may never clear. */
    uint32_t spins = 100000u;
    while (spins-- && (REG_READ(IWDG->sr) & (IWDG_SR_PVU | IWDG_SR_RVU))) {
    }
    REG_WRITE(IWDG->kr, IWDG_KEY_RELOAD);
}

void hal_watchdog_feed(struct hal *h)
{
    (void)h;
    REG_WRITE(IWDG->kr, IWDG_KEY_RELOAD);
}

bool hal_reset_by_power(struct hal *h)
{
    (void)h;
    /* The watchdog (IWDG or WWDG) or a software reset (a fault, hal_restart) ended the
     * last run; otherwise it was power-on, brown-out or the reset pin. */
    uint32_t csr = REG_READ(RCC->csr);
    REG_WRITE(RCC->csr, csr | RCC_CSR_RMVF); /* clear them: the next boot sees its own cause */
    return (csr & (RCC_CSR_IWDGRSTF | RCC_CSR_WWDGRSTF | RCC_CSR_SFTRSTF)) == 0u;
}
