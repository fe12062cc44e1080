/* clock.c - clock tree with fall-backs, the SysTick time base (hal_clock_us) and the
 * interrupt mask of the core's critical sections (hal_irq_save/restore).
 *
 * A servo must boot on a bad crystal: every ready bit is waited for with a time-out, and
 * the tree falls back HSE x 9 (72 MHz) -> HSI / 2 x 16 (64 MHz) -> HSI (8 MHz). The
 * frequencies that result are kept in struct hal for the baud rate, PWM and time base. */
#include "hal_stm32f1.h"
#include "stm32f1_regs.h"

/* Spins of a ready-bit wait: at least ~20 ms on the 8 MHz HSI (HSE start-up is 2 ms
 * typical); PLL lock takes ~200 us. */
#define HSE_SPINS 40000u
#define PLL_SPINS 10000u

/* QEMU's stm32vldiscovery models no RCC (it reads 0) and clocks the core at 24 MHz. */
#define NO_RCC_HZ 24000000u

static bool wait_set(const reg32 *r, uint32_t mask, uint32_t want, uint32_t spins)
{
    while (spins--)
        if ((REG_READ(*r) & mask) == want)
            return true;
    return false;
}

/* Start the PLL with the given source and multiplier and switch SYSCLK to it. */
static bool pll_start(uint32_t cfgr)
{
    REG_WRITE(RCC->cfgr, cfgr); /* SW still HSI: source, multiplier, bus prescalers */
    REG_SET(RCC->cr, RCC_CR_PLLON);
    if (!wait_set(&RCC->cr, RCC_CR_PLLRDY, RCC_CR_PLLRDY, PLL_SPINS)) {
        REG_CLEAR(RCC->cr, RCC_CR_PLLON);
        return false;
    }
    REG_WRITE(RCC->cfgr, cfgr | RCC_CFGR_SW_PLL);
    if (!wait_set(&RCC->cfgr, RCC_CFGR_SWS_MASK, RCC_CFGR_SWS_PLL, PLL_SPINS)) {
        REG_WRITE(RCC->cfgr, cfgr); /* back to HSI */
        REG_CLEAR(RCC->cr, RCC_CR_PLLON);
        return false;
    }
    return true;
}

/* ADC clock prescaler: the smallest of /2, /4, /6, /8 that keeps the ADC <= 14 MHz.
 * (The bootloader reads no sensor: it leaves the ADC clock at its reset value.) */
static uint32_t adcpre(uint32_t pclk2)
{
#ifdef SERVO_BOOTLOADER
    (void)pclk2;
    return 0;
#else
    uint32_t code = 0;
    while (code < 3u && pclk2 / (2u * (code + 1u)) > 14000000u)
        code++;
    return code << RCC_CFGR_ADCPRE_SHIFT;
#endif
}

/* Each fall-back sets the source and its frequency where it is chosen: one store of
 * each at the end rather than a switch over the source (code size, both images). */
void clock_init(struct hal *h)
{
    /* Two wait states and the prefetch buffer before anything runs faster than 24 MHz;
     * harmless at 8 MHz should the PLL never come. */
    REG_WRITE(FLASH->acr, FLASH_ACR_PRFTBE | FLASH_ACR_LATENCY(2));
    uint32_t bus = RCC_CFGR_PPRE1_DIV2; /* APB1 <= 36 MHz; AHB and APB2 undivided */
    uint8_t source = CLOCK_HSE_PLL;
    uint32_t hz = 72000000u;

    REG_SET(RCC->cr, RCC_CR_HSEON);
    if (wait_set(&RCC->cr, RCC_CR_HSERDY, RCC_CR_HSERDY, HSE_SPINS) &&
        pll_start(bus | adcpre(72000000u) | RCC_CFGR_PLLSRC_HSE | RCC_CFGR_PLLMUL(9))) {
        REG_SET(RCC->cr, RCC_CR_CSSON); /* a crystal that fails later raises NMI: reset */
    } else {
        REG_CLEAR(RCC->cr, RCC_CR_HSEON);
        source = CLOCK_HSI_PLL;
        hz = 64000000u;
        if (!pll_start(bus | adcpre(64000000u) | RCC_CFGR_PLLMUL(16))) {
            /* Plain HSI: no wait state, APB1 undivided. On silicon HSION cannot be off
             * while HSI clocks the core, so a CR that reads 0 means there is no RCC. */
            REG_WRITE(RCC->cfgr, adcpre(8000000u));
            REG_WRITE(FLASH->acr, FLASH_ACR_PRFTBE | FLASH_ACR_LATENCY(0));
            source = CLOCK_HSI;
            hz = 8000000u;
            if (REG_READ(RCC->cr) == 0u) {
                source = CLOCK_NO_RCC;
                hz = NO_RCC_HZ;
            }
        }
    }
    h->clock_source = source;
    h->sysclk_hz = hz;
    h->pclk2_hz = hz;
    /* APB1 is divided (bus) only on the PLL's 64 and 72 MHz: the 8 MHz HSI and QEMU's
     * 24 MHz never exceed 36 MHz. */
    _Static_assert(NO_RCC_HZ <= 36000000u, "QEMU's clock: APB1 undivided");
    bool div2 = hz > 36000000u;
    h->pclk1_hz = div2 ? hz / 2u : hz;
    /* APB1 timers run at twice PCLK1 whenever APB1 is divided (RM0008 §7.2): at the
     * system clock either way. */
    h->tim_apb1_hz = hz;
    h->cycles_per_us = hz / 1000000u;
}

void clock_tick_start(struct hal *h)
{
#ifndef SERVO_BOOTLOADER
    /* 10 s before the 32-bit microsecond clock wraps (71.6 min), as on the host: every
     * run of the application, under QEMU and on silicon, crosses the wrap early on. */
    h->tick_us = 0u - 10000000u;
#endif
    h->tick_reload = h->cycles_per_us * 1000u - 1u;
    REG_WRITE(SCB->shp[SCB_SHP_SYSTICK], PRIO_SYSTICK);
    REG_WRITE(SYSTICK->rvr, h->tick_reload);
    REG_WRITE(SYSTICK->cvr, 0);
    REG_WRITE(SYSTICK->csr, SYSTICK_CSR_CLKSOURCE | SYSTICK_CSR_TICKINT | SYSTICK_CSR_ENABLE);
}

/* SysTick, 1 kHz, in RAM: the time base keeps running while the flash is busy. */
RAMFUNC void systick_handler(void)
{
    hal_stm32.tick_us += 1000u;
}

/* Microseconds: the tick count plus the cycles SysTick has counted down since its last
 * reload. If the tick is pending but its handler has not run (this runs with it
 * masked, or before it), the counter has already wrapped: count that period here. */
RAMFUNC uint32_t hal_clock_us(struct hal *h)
{
    for (;;) {
        uint32_t base = h->tick_us;
        uint32_t v = REG_READ(SYSTICK->cvr), cycles;
        if (REG_READ(SCB->icsr) & SCB_ICSR_PENDSTSET) {
            v = REG_READ(SYSTICK->cvr);
            /* At 0 the wrap has pended but not yet reloaded: one cycle short of it. */
            cycles = v ? h->tick_reload + 1u + (h->tick_reload - v) : h->tick_reload;
        } else {
            cycles = h->tick_reload - v;
        }
        if (base == h->tick_us)
            return base + cycles / h->cycles_per_us;
    }
}

/* Mask USART1 (and anything at its priority or below) with BASEPRI; SysTick runs on. */
uint32_t hal_irq_save(struct hal *h)
{
    (void)h;
    uint32_t old;
    CPU_BASEPRI_GET(old);
    CPU_BASEPRI_MAX(PRIO_USART1);
    return old;
}

void hal_irq_restore(struct hal *h, uint32_t state)
{
    (void)h;
    CPU_BASEPRI_SET(state);
}
