/* boot.h - the power-on decision, shared by the STM32 bootloader and the host model of
 * a servo (servo_power_on). Main loop / bootloader only, before anything else runs. */
#ifndef BOOT_H
#define BOOT_H

#include <stdbool.h>
#include <stdint.h>

#include "hal.h"

/* Install a verified update if one is waiting, then say whether the application slot
 * holds a valid image for this model (start it) or not (stay in the loader).
 *
 * A staged image is installed when the install mark is set (image.h), the staging slot
 * holds a valid image and it differs from the application slot: page by page, erase then program then compare. A power cut
 * anywhere in the copy leaves the staging copy valid and the slots different, so the
 * next boot simply copies again. Once the slots match, the staging copy is consumed
 * (its first page erased). Nothing is written when there is nothing to install. */
bool boot_install(struct hal *hal, uint16_t model);

#endif
