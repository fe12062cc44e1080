/* qemu_flash.c - the QEMU build's flash (CMake preset `qemu`, in place of flash.c): QEMU's
 * stm32vldiscovery has no flash controller and its flash is ROM to the guest, so the
 * store's pages are written to RAM behind the same HAL calls, with flash's rules (erase
 * to 0xFF, program an aligned half-word that was erased; writing 0x0000 over anything
 * is allowed, as on the FPEC). Settings persist until QEMU stops.
 *
 * Where: the STM32F100 QEMU models has 8 KiB of RAM; every image is held to 6 KiB
 * (linker scripts, BUDGET_RAM), so the top 2 KiB, 0x20001800-0x20001FFF, belong to no
 * image: two page buffers. The store writes only two of its four pages at a time (the
 * active page, and the next in rotation that a compaction fills), and reads the others
 * only at power-up, which under QEMU is never again (-no-reboot; no instruction restarts
 * the MCU: an update cannot complete without a flash controller). So the buffers hold
 * the two most recently written pages; writing a third takes the buffer of the page
 * written least recently, which then reads as what QEMU's flash holds there (the tests
 * and `make qemu` load it erased), as if it had been erased. Newest committed page and
 * the page being compacted into are always the two most recent: the store's rotation
 * never writes elsewhere.
 *
 * Both slots read QEMU's flash as flash.c maps them; erasing or programming them fails,
 * as flash.c does under QEMU (no FPEC): an update is refused at its first block.
 * Main loop only. */
#include <string.h>

#include "hal_stm32f1.h"

#define RAM_PAGES 2u
#define RAM_FLASH_BASE 0x20001800u /* 0x20000000 + BUDGET_RAM (6 KiB) */
#define NO_BUFFER 0xFFu

_Static_assert(RAM_FLASH_BASE + RAM_PAGES * HAL_FLASH_PAGE_BYTES == 0x20002000u,
               "two pages at the top of the STM32F100's 8 KiB");

extern const uint8_t _store_start[], _app_start[], _ram_end[]; /* stm32f103x8-memory.ld */

struct ram_flash {
    uint8_t buffer[HAL_FLASH_PAGES]; /* the store page's buffer + 1, 0 = QEMU's flash */
    uint8_t newest;                  /* buffer + 1 written last, 0 = none yet */
    uint8_t used;                    /* buffers handed out so far */
};

static struct ram_flash ram;

/* Page buffer b (0 or 1). */
static uint8_t *ram_page(uint32_t b)
{
    uint8_t *page = (uint8_t *)(uintptr_t)(RAM_FLASH_BASE + b * HAL_FLASH_PAGE_BYTES);
    return page;
}

/* QEMU's flash under page p: the store's 4 KiB, then both slots. */
static const uint8_t *rom_page(uint8_t p)
{
    if (p < HAL_FLASH_PAGES)
        return _store_start + (uint32_t)p * HAL_FLASH_PAGE_BYTES;
    if (p >= HAL_PAGE_APP && p < HAL_PAGES_ALL)
        return _app_start + (uint32_t)(p - HAL_PAGE_APP) * HAL_FLASH_PAGE_BYTES;
    return 0;
}

const uint8_t *hal_flash_page(struct hal *h, uint8_t p)
{
    (void)h;
    if (p < HAL_FLASH_PAGES && ram.buffer[p])
        return ram_page(ram.buffer[p] - 1u);
    return rom_page(p);
}

/* The RAM buffer of store page p for a write, taking one if p has none: a fresh one,
 * else the one not written last (its page reads as QEMU's flash again). Starts as what
 * the page read before. 0 for a page outside the store, or an image that spills into
 * the buffers (cannot link: BUDGET_RAM). */
static uint8_t *page_for_write(uint8_t p)
{
    if (p >= HAL_FLASH_PAGES || _ram_end > ram_page(0))
        return 0;
    if (!ram.buffer[p]) {
        uint8_t b = ram.used < RAM_PAGES ? ram.used++ : (uint8_t)(ram.newest == 1u ? 1u : 0u);
        for (uint8_t q = 0; q < HAL_FLASH_PAGES; q++)
            if (ram.buffer[q] == b + 1u)
                ram.buffer[q] = 0;
        memcpy(ram_page(b), rom_page(p), HAL_FLASH_PAGE_BYTES);
        ram.buffer[p] = (uint8_t)(b + 1u);
    }
    ram.newest = ram.buffer[p];
    return ram_page(ram.buffer[p] - 1u);
}

bool hal_flash_erase(struct hal *h, uint8_t p)
{
    uint8_t *page = page_for_write(p);
    if (!page) {
        h->flash_errors++;
        return false;
    }
    memset(page, 0xFF, HAL_FLASH_PAGE_BYTES);
    return true;
}

bool hal_flash_program(struct hal *h, uint8_t p, uint16_t off, uint16_t value)
{
    uint8_t *page = (off & 1u) || off >= HAL_FLASH_PAGE_BYTES ? 0 : page_for_write(p);
    if (!page) {
        h->flash_errors++;
        return false;
    }
    uint16_t was = (uint16_t)(page[off] | page[off + 1u] << 8);
    if (was != 0xFFFFu && value != 0u) {
        h->flash_errors++; /* the FPEC's PGERR: programming a half-word not erased */
        return false;
    }
    page[off] = (uint8_t)value;
    page[off + 1u] = (uint8_t)(value >> 8);
    return true;
}

/* hal.h hal_uid: QEMU's STM32F100 has no unique-ID region, so each instance's 12 bytes
 * sit at the top of its 128 KiB flash, 0x0801FFF0, where the test loads them
 * (-device loader; tools/qemu_servo.py --uid). Nothing else lives there. */
#define QEMU_UID_ADDR 0x0801FFF0u

const uint8_t *hal_uid(struct hal *h)
{
    (void)h;
    return (const uint8_t *)QEMU_UID_ADDR;
}
