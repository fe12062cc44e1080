/* port_hal.c - the port's one struct hal, which main.c or boot_main.c define on the MCU,
 * for the tests that run the port's drivers without either. */
#include "hal_stm32f1.h"

struct hal hal_stm32;
