/* main.c - the servo on an STM32F103: bring the port up, then one servo in the main loop
 * for ever (servo_init starts the independent watchdog, servo_poll feeds it). Interrupt
 * context is the USART1 receive interrupt (servo_rx_isr) and the SysTick time base;
 * everything else runs here. The board is chosen at build time (CMake BOARD, which sets
 * SERVO_BOARD and board/<name>/board_pins.h). */
#include "hal_stm32f1.h"
#include "servo.h"

#ifndef SERVO_BOARD
#error "SERVO_BOARD (board_arm, board_base, ...) comes from CMake's BOARD"
#endif

struct hal hal_stm32;
static struct servo servo;

int main(void)
{
    struct hal *h = &hal_stm32;
    gpio_init();          /* bridge asleep, RS485 driver off */
    clock_init(h);        /* from the reset clock (HSI) the bootloader left */
    clock_tick_start(h);  /* hal_clock_us() */
    uart_init(h);         /* receiver on, interrupt still off */
    motor_init(h, &SERVO_BOARD);
    servo_init(&servo, &SERVO_BOARD, h); /* table, stored EEPROM, baud, motor off,
                                            watchdog started */
    uart_start(h, &servo); /* from here bytes reach the frame receiver */
    bool emulated = h->clock_source == CLOCK_NO_RCC;
    for (;;) {
        servo_poll(&servo); /* feeds the watchdog while the control tick runs */
        /* Under QEMU only, sleep until the next interrupt (SysTick, a byte) so that the
         * emulator's I/O thread gets to deliver received bytes; a spinning guest starves
         * it. On silicon the loop spins: an answer due now must not wait for a tick. */
        if (emulated)
            CPU_WFI();
    }
}
