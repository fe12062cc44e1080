/* port_flash.c - both builds of hal/stm32f1/flash.c in one test program: the
 * application's (app_flash_*: may not write its own slot) and the bootloader's
 * (boot_flash_*: installs into the application slot, feeds the IWDG). The core calls
 * hal_flash_*(); which build answers is which image the test says runs. */
#include "port_flash.h"

uint8_t port_image = PORT_APP;

const uint8_t *hal_flash_page(struct hal *h, uint8_t p)
{
    return port_image == PORT_BOOT ? boot_flash_page(h, p) : app_flash_page(h, p);
}

bool hal_flash_erase(struct hal *h, uint8_t p)
{
    return port_image == PORT_BOOT ? boot_flash_erase(h, p) : app_flash_erase(h, p);
}

bool hal_flash_program(struct hal *h, uint8_t p, uint16_t off, uint16_t value)
{
    return port_image == PORT_BOOT ? boot_flash_program(h, p, off, value)
                                   : app_flash_program(h, p, off, value);
}
