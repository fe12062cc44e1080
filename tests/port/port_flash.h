/* port_flash.h - the two builds of hal/stm32f1/flash.c a test program links (see
 * port_flash.c), and which one answers the core's hal_flash_*() calls. */
#ifndef PORT_FLASH_H
#define PORT_FLASH_H

#include <stdbool.h>
#include <stdint.h>

#include "hal.h"

enum { PORT_APP, PORT_BOOT };
extern uint8_t port_image;

const uint8_t *app_flash_page(struct hal *h, uint8_t p);
bool app_flash_erase(struct hal *h, uint8_t p);
bool app_flash_program(struct hal *h, uint8_t p, uint16_t off, uint16_t value);
const uint8_t *boot_flash_page(struct hal *h, uint8_t p);
bool boot_flash_erase(struct hal *h, uint8_t p);
bool boot_flash_program(struct hal *h, uint8_t p, uint16_t off, uint16_t value);

#endif
