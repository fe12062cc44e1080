/* flash.c - the core's flash pages through the flash program/erase controller (FPEC).
 * hal.h numbers them; the linker scripts (board/stm32f103x8-memory.ld) place them:
 *   pages 0 .. HAL_FLASH_PAGES-1     the store, the top 4 KiB (region STORE)
 *   HAL_PAGE_APP .. HAL_PAGES_ALL-1  the application slot then the staging slot, which
 *                                    touch: page HAL_PAGE_APP + n is _app_start + n KiB
 *   HAL_PAGE_BOOTREC                 the boot record, the last KiB of the bootloader's
 *                                    8 KiB region (region BOOTREC, 0x08001C00)
 * Any other page number fails (a null view, false for erase and program). The
 * bootloader's own 7 KiB of code are never among them. The application (built without
 * SERVO_BOOTLOADER) may not erase or program its own slot, only the bootloader installs
 * into it; both write the boot record (boot.h).
 *
 * While the FPEC works (20-40 ms for a page erase, ~50 us for a half-word) any flash
 * read stalls the CPU. The start-and-wait step therefore runs from RAM, so the USART1
 * and SysTick interrupts (also in RAM, vectors in RAM) are taken all along: no received
 * byte is lost to an erase. Main loop only. */
#include "hal_stm32f1.h"

_Static_assert(HAL_FLASH_PAGE_BYTES == 1024u, "STM32F103x8/xB pages are 1 KiB");
_Static_assert(HAL_FLASH_PAGES * HAL_FLASH_PAGE_BYTES == 4096u,
               "the linker script reserves 4 KiB (STORE) for the store");
_Static_assert(HAL_SLOT_PAGES * HAL_FLASH_PAGE_BYTES == 26u * 1024u,
               "the linker script's slots (APP, STAGING) are 26 KiB each");
_Static_assert(HAL_PAGE_APP == HAL_FLASH_PAGES && HAL_PAGE_BOOTREC < 256u,
               "page numbers: the store, both slots, the boot record, in a uint8_t");

extern const uint8_t _store_start[], _app_start[], _bootrec_start[]; /* stm32f103x8-memory.ld */

/* Longest wait for BSY: an erase is 40 ms at most; the loop is >= 4 cycles. */
#define BUSY_SPINS 2000000u

const uint8_t *hal_flash_page(struct hal *h, uint8_t p)
{
    (void)h;
    if (p < HAL_FLASH_PAGES)
        return _store_start + (uint32_t)p * HAL_FLASH_PAGE_BYTES;
    if (p >= HAL_PAGE_APP && p < HAL_PAGES_ALL)
        return _app_start + (uint32_t)(p - HAL_PAGE_APP) * HAL_FLASH_PAGE_BYTES;
    if (p == HAL_PAGE_BOOTREC)
        return _bootrec_start;
    return 0;
}

/* A page this image may erase and program: the store and the staging slot; the
 * application slot only from the bootloader (the application runs from it). */
static const uint8_t *writable(struct hal *h, uint8_t p)
{
#ifndef SERVO_BOOTLOADER
    if (p >= HAL_PAGE_APP && p < HAL_PAGE_STAGING)
        return 0;
#endif
    return hal_flash_page(h, p);
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
#ifdef SERVO_BOOTLOADER
    /* The bootloader does not start the IWDG before it installs an image, but on a part
     * whose option bytes start it in hardware (~410 ms at reset) a 27-page install takes
     * ~2 s: feeding at every operation (each < 40 ms) keeps it alive. Harmless when the
     * IWDG is not running. */
    IWDG->kr = IWDG_KEY_RELOAD;
#endif
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
    const uint8_t *page = writable(h, p);
    if (!page)
        return false;
    return fpec(h, FLASH_CR_PER, (uint32_t)(uintptr_t)page, 0);
}

bool hal_flash_program(struct hal *h, uint8_t p, uint16_t off, uint16_t value)
{
    const uint8_t *page = writable(h, p);
    if (!page || (off & 1u) || off >= HAL_FLASH_PAGE_BYTES)
        return false;
    const uint8_t *at = page + off;
    return fpec(h, FLASH_CR_PG, (uint32_t)(uintptr_t)at, value) &&
           *(const volatile uint16_t *)at == value;
}
