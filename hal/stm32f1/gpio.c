/* gpio.c - pins: configuration, levels, the board outputs' safe state (the photo
 * switches' pull-ups too) and the RS485 terminator. Reading the switches is motor.c's,
 * with the other sensors. */
#include "hal_stm32f1.h"

/* For GPIO_IN_PULL the output latch picks up (set it with gpio_write) or down. */
void gpio_mode(uint8_t pin, uint32_t mode)
{
    if (pin == PIN_NONE)
        return;
    struct gpio_regs *g = GPIO(pin >> 4);
    uint32_t n = pin & 15u, shift = (n & 7u) * 4u;
    reg32 *cr = n < 8u ? &g->crl : &g->crh;
    REG_WRITE(*cr, (REG_READ(*cr) & ~(0xFu << shift)) | (mode << shift));
}

/* Outputs low first (bridge asleep, driver enable off, terminator out), then driven. */
void gpio_init(void)
{
    REG_SET(RCC->apb2enr, RCC_APB2ENR_IOPAEN | RCC_APB2ENR_IOPBEN | RCC_APB2ENR_IOPCEN);
    gpio_write(BOARD_PIN_DRIVER_EN, false);
    gpio_mode(BOARD_PIN_DRIVER_EN, GPIO_OUT_PP_2MHZ);
    gpio_write(BOARD_PIN_RS485_DE, false);
    gpio_mode(BOARD_PIN_RS485_DE, GPIO_OUT_PP_2MHZ);
    gpio_write(BOARD_PIN_RS485_TERM, false);
    gpio_mode(BOARD_PIN_RS485_TERM, GPIO_OUT_PP_2MHZ);
#ifndef SERVO_BOOTLOADER /* it never reads the switches: reset's floating input will do */
    if (BOARD_PHOTO) {
        /* Open-collector sensors: pulled toward "interrupted" if a wire comes off. */
        gpio_write(BOARD_PIN_PHOTO1, BOARD_PHOTO_ACTIVE_HIGH);
        gpio_write(BOARD_PIN_PHOTO2, BOARD_PHOTO_ACTIVE_HIGH);
        gpio_mode(BOARD_PIN_PHOTO1, GPIO_IN_PULL);
        gpio_mode(BOARD_PIN_PHOTO2, GPIO_IN_PULL);
    }
#endif
}

/* What board_pins.h fitted: the same source as the board's own description. */
uint8_t hal_capabilities(struct hal *h)
{
    (void)h;
    return BOARD_FITTINGS;
}

void hal_rs485_termination(struct hal *h, bool on)
{
    (void)h;
    gpio_write(BOARD_PIN_RS485_TERM, on);
}
