/* uid.c - the MCU's unique identity (hal.h hal_uid): the STM32F1's 96-bit unique device
 * ID, factory-programmed in system memory (RM0008 §30.2). The QEMU build has its own in
 * qemu_flash.c: QEMU's STM32F100 models no such region. */
#include "hal_stm32f1.h"

#define UID_BASE 0x1FFFF7E8u

const uint8_t *hal_uid(struct hal *h)
{
    (void)h;
    return (const uint8_t *)UID_BASE;
}
