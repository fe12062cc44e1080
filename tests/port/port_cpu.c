/* port_cpu.c - what hal/stm32f1/startup.c gives the port's other files, for their host
 * build on the register models: the fault path and hal_restart() (outputs safe, then
 * SYSRESETREQ through the SCB model, which resets the models and stops the code under
 * test). startup.c itself (vector table, the copy of .data and RAM code) is the
 * linker's and the MCU's business and is not compiled here. */
#include "hal_stm32f1.h"

void fault_reset(void)
{
    gpio_write(BOARD_PIN_DRIVER_EN, false);
    gpio_write(BOARD_PIN_RS485_DE, false);
    REG_WRITE(SCB->aircr, SCB_AIRCR_VECTKEY | SCB_AIRCR_SYSRESETREQ);
    __builtin_unreachable(); /* the model's reset does not return */
}

void hal_restart(struct hal *h)
{
    (void)h;
    fault_reset();
}
