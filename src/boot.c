/* boot.c - install a staged update, then decide what runs; the boot record (boot.h). */
#include <stddef.h>
#include <string.h>

#include "boot.h"
#include "image.h"

/* Copy one page of the staging slot over the same page of the application slot. */
static bool copy_page(struct hal *hal, uint8_t page)
{
    return image_write_page(hal, (uint8_t)(HAL_PAGE_APP + page),
                            hal_flash_page(hal, (uint8_t)(HAL_PAGE_STAGING + page)),
                            HAL_FLASH_PAGE_BYTES);
}

/* Do the slots hold the same first length bytes? */
static bool slots_equal(struct hal *hal, uint32_t length)
{
    for (uint8_t p = 0; (uint32_t)p * HAL_FLASH_PAGE_BYTES < length; p++) {
        uint32_t left = length - (uint32_t)p * HAL_FLASH_PAGE_BYTES;
        size_t n = left < HAL_FLASH_PAGE_BYTES ? left : HAL_FLASH_PAGE_BYTES;
        if (memcmp(hal_flash_page(hal, (uint8_t)(HAL_PAGE_APP + p)),
                   hal_flash_page(hal, (uint8_t)(HAL_PAGE_STAGING + p)), n) != 0)
            return false;
    }
    return true;
}

bool boot_install(struct hal *hal, uint16_t model)
{
    struct image_info staged;
    if (image_marked(hal) && image_valid(hal, HAL_PAGE_STAGING, model, &staged)) {
        if (!slots_equal(hal, staged.length)) {
            uint8_t pages = (uint8_t)((staged.length + HAL_FLASH_PAGE_BYTES - 1u) /
                                      HAL_FLASH_PAGE_BYTES);
            for (uint8_t p = 0; p < pages; p++)
                if (!copy_page(hal, p))
                    break; /* the slots still differ: the next boot tries again */
        }
        /* Installed: no start of the new image has failed yet, so the boot record starts
         * empty; then consume the staged copy, so an image written later by other means
         * (a programmer) is never overwritten by it. A cut in the first erase comes back
         * here at the next boot (the staged copy is still there); a cut in the second
         * leaves the page torn, which fails the check like an erased one. */
        if (slots_equal(hal, staged.length)) {
            (void)hal_flash_erase(hal, HAL_PAGE_BOOTREC);
            (void)hal_flash_erase(hal, HAL_PAGE_STAGING);
        }
    }
    return image_valid(hal, HAL_PAGE_APP, model, 0);
}

/* The record at r: unconfirmed starts, and in *end the byte offset of its first erased
 * half-word (HAL_FLASH_PAGE_BYTES: full). */
static inline uint32_t record_read(const uint8_t *r, uint32_t *end)
{
    uint32_t starts = 0, off = 0;
    for (; off < HAL_FLASH_PAGE_BYTES; off += 2u) {
        uint8_t hi = r[off + 1u]; /* little-endian half-word */
        if ((r[off] & hi) == 0xFFu)
            break; /* erased: the end of the log */
        starts = hi == 0xFFu ? starts + 1u : 0u; /* high byte erased: a START, else a CONFIRM */
    }
    *end = off;
    return starts;
}

bool boot_start(struct hal *hal, uint16_t model)
{
    uint32_t end;
    bool power = hal_reset_by_power(hal); /* read once per boot: it clears the flags */
    if (!boot_install(hal, model))
        return false;
    uint32_t starts = record_read(hal_flash_page(hal, HAL_PAGE_BOOTREC), &end);
    /* A start that ended because the power went proved nothing either way (a robot
     * switched off within seconds of power-up): a CONFIRM on its behalf. Only the
     * watchdog or a fault ending a start counts it as failed. */
    if (starts && power && end < HAL_FLASH_PAGE_BYTES &&
        hal_flash_program(hal, HAL_PAGE_BOOTREC, (uint16_t)end, BOOT_MARK_CONFIRM)) {
        starts = 0;
        end += 2u;
    }
    if (starts >= BOOT_STARTS_MAX)
        return false;
    /* A full record (the application erases it at half) or a flash error only means
     * this start goes uncounted: start all the same. */
    if (end < HAL_FLASH_PAGE_BYTES)
        (void)hal_flash_program(hal, HAL_PAGE_BOOTREC, (uint16_t)end, BOOT_MARK_START);
    return true;
}

/* The application's side (the bootloader's build leaves it out, so that record_read()
 * has one caller there and is inlined). */
#ifndef SERVO_BOOTLOADER
uint16_t boot_unconfirmed(struct hal *hal, uint16_t *end)
{
    const uint8_t *r = hal_flash_page(hal, HAL_PAGE_BOOTREC);
    uint32_t e = HAL_FLASH_PAGE_BYTES, starts = 0;
    if (r != NULL)
        starts = record_read(r, &e);
    *end = (uint16_t)e;
    return (uint16_t)starts;
}

bool boot_confirm(struct hal *hal, bool quiet)
{
    const uint8_t *r = hal_flash_page(hal, HAL_PAGE_BOOTREC);
    if (r == NULL)
        return true; /* a port without a boot record */
    /* A CONFIRM at the end of the log. Marks a torn erase left past the end join the
     * log once it reaches them, and may read as starts: confirm again past them. */
    uint16_t end;
    while (boot_unconfirmed(hal, &end) != 0u && end < HAL_FLASH_PAGE_BYTES)
        if (!hal_flash_program(hal, HAL_PAGE_BOOTREC, end, BOOT_MARK_CONFIRM))
            break; /* a flash error: leave it to the erase below */
    /* Half full, or marks past the end: erase it while the servo is quiet (an erased
     * record confirms as well as a CONFIRM does). */
    bool tidy = end >= BOOT_TIDY_BYTES;
    for (uint16_t off = end; off < HAL_FLASH_PAGE_BYTES && !tidy; off++)
        tidy = r[off] != 0xFFu;
    if (!tidy)
        return true;
    if (!quiet)
        return false;
    (void)hal_flash_erase(hal, HAL_PAGE_BOOTREC);
    return true;
}
#endif
