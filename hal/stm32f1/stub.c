/* stub.c - link stub for the STM32F103 until the real port lands (issue 7): a vector
 * table, .data/.bss start-up and a main loop around one servo, with HAL functions that
 * touch no hardware. It proves the core links for Cortex-M3 with no floating point and
 * shows its size; it does not drive a board. */
#include <stdint.h>
#include <string.h>

#include "hal.h"
#include "servo.h"

#ifndef SERVO_BOARD
#define SERVO_BOARD board_arm
#endif

struct hal {
    uint32_t unused;
};

static struct hal stub_hal;
static struct servo stub_servo;

uint32_t hal_clock_us(struct hal *h) { (void)h; return 0; }
void hal_uart_set_baud(struct hal *h, uint32_t baud) { (void)h; (void)baud; }
void hal_uart_send(struct hal *h, const uint8_t *buf, uint16_t len) { (void)h; (void)buf; (void)len; }
bool hal_uart_tx_busy(struct hal *h) { (void)h; return false; }
uint32_t hal_irq_save(struct hal *h) { (void)h; return 0; }
void hal_irq_restore(struct hal *h, uint32_t state) { (void)h; (void)state; }

/* The store's pages: the last HAL_FLASH_PAGES KiB of a 64 KiB part. */
const uint8_t *hal_flash_page(struct hal *h, uint8_t p)
{
    (void)h;
    return (const uint8_t *)(0x08010000u - (HAL_FLASH_PAGES - p) * HAL_FLASH_PAGE_BYTES);
}
bool hal_flash_erase(struct hal *h, uint8_t p) { (void)h; (void)p; return false; }
bool hal_flash_program(struct hal *h, uint8_t p, uint16_t off, uint16_t value) { (void)h; (void)p; (void)off; (void)value; return false; }

void hal_motor_enable(struct hal *h, bool on) { (void)h; (void)on; }
void hal_motor_drive(struct hal *h, int16_t duty) { (void)h; (void)duty; }
int32_t hal_motor_position(struct hal *h) { (void)h; return 0; }
uint16_t hal_motor_current_ma(struct hal *h) { (void)h; return 0; }
uint16_t hal_supply_mv(struct hal *h) { (void)h; return 12000; }
int16_t hal_temperature_dc(struct hal *h) { (void)h; return 250; }
uint8_t hal_photo_switches(struct hal *h) { (void)h; return 0; }
void hal_rs485_termination(struct hal *h, bool on) { (void)h; (void)on; }
void hal_watchdog_start(struct hal *h) { (void)h; }
void hal_watchdog_feed(struct hal *h) { (void)h; }

int main(void);
void stub_reset(void);

/* USART1 receive interrupt: the only core entry point in interrupt context. */
void stub_usart1_irq(void);
void stub_usart1_irq(void)
{
    servo_rx_isr(&stub_servo, 0);
}

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;

void stub_reset(void)
{
    memcpy(&_sdata, &_sidata, (size_t)((char *)&_edata - (char *)&_sdata));
    memset(&_sbss, 0, (size_t)((char *)&_ebss - (char *)&_sbss));
    main();
    for (;;) {
    }
}

__attribute__((section(".isr_vector"), used)) static void (*const vectors[16 + 38])(void) = {
    [0] = (void (*)(void))(uintptr_t)&_estack,
    [1] = stub_reset,
    [16 + 37] = stub_usart1_irq,
};

int main(void)
{
    servo_init(&stub_servo, &SERVO_BOARD, &stub_hal);
    for (;;)
        servo_poll(&stub_servo);
}
