/* flash.c - the persistent store's pages through the flash program/erase controller
 * (FPEC). The pages are the top HAL_FLASH_PAGES KiB of the part, reserved by the linker
 * script (region STORE) so the application can never grow into them.
 *
 * While the FPEC works (20-40 ms for a page erase, ~50 us for a half-word) any flash
 * read stalls the CPU. The start-and-wait step therefore runs from RAM, so the USART1
 * and SysTick interrupts (also in RAM, vectors in RAM) are taken all along: no received
 * byte is lost to an erase. Main loop only. */
#include "hal_stm32f1.h"

_Static_assert(HAL_FLASH_PAGE_BYTES == 1024u, "STM32F103x8/xB pages are 1 KiB");
_Static_assert(HAL_FLASH_PAGES * HAL_FLASH_PAGE_BYTES == 4096u,
               "the linker script reserves 4 KiB (STORE) for the store");

extern const uint8_t _store_start[]; /* linker script */

/* Longest wait for BSY: an erase is 40 ms at most; the loop is >= 4 cycles. */
#define BUSY_SPINS 2000000u

const uint8_t *hal_flash_page(struct hal *h, uint8_t p)
{
    (void)h;
    return _store_start + (uint32_t)p * HAL_FLASH_PAGE_BYTES;
}

/* In RAM: start the operation that cr selects (PER: erase the page at addr; PG: write
 * value to the half-word at addr) and wait until the FPEC is done. Returns SR. */
static RAMFUNC uint32_t fpec_run(uint32_t cr, uint32_t addr, uint16_t value)
{
    FLASH->cr = cr;
    if (cr & FLASH_CR_PER) {
        FLASH->ar = addr;
        FLASH->cr = cr | FLASH_CR_STRT;
    } else {
        *(volatile uint16_t *)addr = value;
    }
    __asm volatile("dsb" ::: "memory"); /* the start has reached the FPEC: BSY is set */
    uint32_t sr, spins = BUSY_SPINS;
    do {
        sr = FLASH->sr;
    } while ((sr & FLASH_SR_BSY) && --spins);
    FLASH->cr = 0;
    return sr;
}

/* Unlock, run one operation, lock again; true if the FPEC reports success. */
static bool fpec(struct hal *h, uint32_t cr, uint32_t addr, uint16_t value)
{
    if (FLASH->cr & FLASH_CR_LOCK) {
        FLASH->keyr = FLASH_KEY1;
        FLASH->keyr = FLASH_KEY2;
    }
    FLASH->sr = FLASH_SR_EOP | FLASH_SR_PGERR | FLASH_SR_WRPRTERR; /* write 1 to clear */
    uint32_t sr = fpec_run(cr, addr, value);
    FLASH->sr = FLASH_SR_EOP | FLASH_SR_PGERR | FLASH_SR_WRPRTERR;
    FLASH->cr = FLASH_CR_LOCK;
    bool ok = (sr & (FLASH_SR_EOP | FLASH_SR_BSY | FLASH_SR_PGERR | FLASH_SR_WRPRTERR)) ==
              FLASH_SR_EOP;
    if (!ok)
        h->flash_errors++;
    return ok;
}

bool hal_flash_erase(struct hal *h, uint8_t p)
{
    if (p >= HAL_FLASH_PAGES)
        return false;
    return fpec(h, FLASH_CR_PER, (uint32_t)(uintptr_t)hal_flash_page(h, p), 0);
}

bool hal_flash_program(struct hal *h, uint8_t p, uint16_t off, uint16_t value)
{
    if (p >= HAL_FLASH_PAGES || (off & 1u) || off >= HAL_FLASH_PAGE_BYTES)
        return false;
    const uint8_t *at = hal_flash_page(h, p) + off;
    return fpec(h, FLASH_CR_PG, (uint32_t)(uintptr_t)at, value) &&
           *(const volatile uint16_t *)at == value;
}
