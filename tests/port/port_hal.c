/* port_hal.c - the port's one struct hal, which main.c or boot_main.c define on the MCU,
 * for the tests that run the port's drivers without either. */
#include "hal_stm32f1.h"

struct hal hal_stm32;

/* hal_uid() reads system memory on the MCU (hal/stm32f1/uid.c), which the models lack:
 * these tests never enumerate, so a fixed identity serves. */
const uint8_t *hal_uid(struct hal *h)
{
    static const uint8_t uid[HAL_UID_BYTES] = {1};
    (void)h;
    return uid;
}
