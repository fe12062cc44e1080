/* boot.c - install a staged update, then decide what runs (boot.h). */
#include <string.h>

#include "boot.h"
#include "image.h"

/* Copy one page of the staging slot over the same page of the application slot. */
static bool copy_page(struct hal *hal, uint8_t page)
{
    return image_write_page(hal, (uint8_t)(HAL_PAGE_APP + page),
                            hal_flash_page(hal, (uint8_t)(HAL_PAGE_STAGING + page)));
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
        /* Installed: consume the staged copy, so an image written later by other means
         * (a programmer) is never overwritten by it. A cut in this erase leaves the page
         * torn, which fails the check like an erased one. */
        if (slots_equal(hal, staged.length))
            (void)hal_flash_erase(hal, HAL_PAGE_STAGING);
    }
    return image_valid(hal, HAL_PAGE_APP, model, 0);
}
