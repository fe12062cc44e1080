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
#include <stddef.h>

#include "hal_stm32f1.h"

_Static_assert(HAL_FLASH_PAGE_BYTES == 1024u, "STM32F103x8/xB pages are 1 KiB");
_Static_assert(HAL_FLASH_PAGES * HAL_FLASH_PAGE_BYTES == 4096u,
               "the linker script reserves 4 KiB (STORE) for the store");
_Static_assert(HAL_SLOT_PAGES * HAL_FLASH_PAGE_BYTES == 26u * 1024u,
               "the linker script's slots (APP, STAGING) are 26 KiB each");
_Static_assert(HAL_PAGE_APP == HAL_FLASH_PAGES && HAL_PAGE_BOOTREC < 256u,
               "page numbers: the store, both slots, the boot record, in a uint8_t");

extern const uint8_t _store_start[], _app_start[], _bootrec_start[]; /* stm32f103x8-memory.ld */

/* Turns of a BSY wait (fpec_run), each an SR read and an IWDG feed from RAM: at 8 cycles
 * a turn at least 0.44 s at 72 MHz (about 15 on silicon: 0.8 s), longer on slower
 * clocks. The STM32F103 erases a page in 40 ms at most (datasheet); the margin is for a
 * part nobody has timed (README). */
#define BUSY_SPINS 4000000u

/* F_SIZE (RM0008 §30.1): the part's flash in KiB. */
#define F_SIZE (*(const volatile uint16_t *)0x1FFFF7E0u)

const uint8_t *hal_flash_page(struct hal *h, uint8_t p)
{
    (void)h;
    if (p < HAL_FLASH_PAGES)
        return _store_start + (size_t)p * HAL_FLASH_PAGE_BYTES;
    if (p >= HAL_PAGE_APP && p < HAL_PAGES_ALL)
        return _app_start + (size_t)(p - HAL_PAGE_APP) * HAL_FLASH_PAGE_BYTES;
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

/* In RAM, the whole operation: wait for an earlier one to end, unlock, start what cr
 * selects (PER: erase the page at addr; PG: write value to the half-word at addr), wait
 * until it is done, lock again. Returns SR read afresh once BSY has fallen; or
 * FLASH_SR_BSY if BSY stayed set for BUSY_SPINS turns of either wait, and then nothing
 * more is written to the FPEC (FLASH_CR may not be written while BSY): it stays as it
 * is, and the next operation waits for it first. Each turn feeds the IWDG, which nothing
 * else can feed meanwhile (the CPU is here) and which must not cut an erase short. */
static RAMFUNC uint32_t fpec_run(uint32_t cr, uint32_t addr, uint16_t value)
{
    for (bool started = false;; started = true) {
        for (uint32_t spins = BUSY_SPINS; REG_READ(FLASH->sr) & FLASH_SR_BSY;) {
            REG_WRITE(IWDG->kr, IWDG_KEY_RELOAD);
            if (--spins == 0u)
                return FLASH_SR_BSY;
        }
        if (started) {
            REG_WRITE(FLASH->cr, FLASH_CR_LOCK); /* PER and PG off, locked */
            return REG_READ(FLASH->sr);
        }
        if (REG_READ(FLASH->cr) & FLASH_CR_LOCK) {
            REG_WRITE(FLASH->keyr, FLASH_KEY1);
            REG_WRITE(FLASH->keyr, FLASH_KEY2);
        }
        /* Write 1 to clear the flags an earlier operation left: the verdict is this one's. */
        REG_WRITE(FLASH->sr, FLASH_SR_EOP | FLASH_SR_PGERR | FLASH_SR_WRPRTERR);
        REG_WRITE(FLASH->cr, cr);
        if (cr & FLASH_CR_PER) {
            REG_WRITE(FLASH->ar, addr);
            REG_WRITE(FLASH->cr, cr | FLASH_CR_STRT);
        } else {
            REG_WRITE(*(volatile uint16_t *)(uintptr_t)addr, value);
        }
        CPU_DSB(); /* the start has reached the FPEC: BSY is set */
    }
}

/* Is this the part the flash map was built for? 64 KiB (the map's) or 128 (F_SIZE
 * reads 64 to 191 on no other part): both medium density, whose pages are 1 KiB; the
 * STM32F1 lines with 2 KiB pages are larger, or are the STM32F105/107, which come in no
 * 48-pin package (the page size itself cannot be read: README). RCC_CR reads 0 only
 * where there is no RCC, an emulator: it has neither an FPEC nor F_SIZE (reading it
 * there would fault). */
static bool part_fits(void)
{
    return REG_READ(RCC->cr) != 0u && REG_READ(F_SIZE) - 64u < 128u;
}

/* One operation; true if the FPEC reports success. Nothing is started on a part the map
 * does not fit. */
static bool fpec(struct hal *h, uint32_t cr, uint32_t addr, uint16_t value)
{
    uint32_t sr = part_fits() ? fpec_run(cr, addr, value) : 0u;
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
           REG_READ(*(const volatile uint16_t *)at) == value;
}
