/* port_app.h - the arm servo on the models, for the port tests that run the whole
 * application: power-on, the bootloader's decision (boot.h, through the bootloader's
 * build of flash.c), the bring-up of hal/stm32f1/main.c, its main loop, and the host's
 * side of the bus. (port.boot runs boot_main.c itself.) */
#ifndef PORT_APP_H
#define PORT_APP_H

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "boot.h"
#include "hal_stm32f1.h"
#include "model.h"
#include "port_board.h"
#include "port_flash.h"
#include "port_wire.h"
#include "servo.h"

static struct servo port_servo;
static jmp_buf port_stopped;

static inline void port_no_violation(void)
{
    if (model.violations)
        fail_msg("%u violation(s), the first: %s", model.violations, model.violation);
}

/* A fresh board: the flash erased, the crystal and PLL as given, the board's analog
 * inputs, the driver enable watched. */
static inline void port_board_new(bool crystal, bool pll)
{
    model_init();
    model.rcc.crystal = crystal;
    model.rcc.pll_locks = pll;
    model.usart.de_pin = BOARD_PIN_RS485_DE;
    model.gpio.watch = BOARD_PIN_RS485_DE;
    model.adc.analog = port_board_analog;
}

/* What the bootloader does before it branches: its pins, boot_start() through its own
 * build of flash.c, the watchdog. Returns boot_start()'s verdict. */
static inline bool port_bootloader(void)
{
    memset(&hal_stm32, 0, sizeof hal_stm32);
    port_image = PORT_BOOT;
    gpio_init();
    bool start = boot_start(&hal_stm32, BOARD_MODEL_ARM);
    hal_watchdog_start(&hal_stm32);
    return start;
}

/* main.c's bring-up, from the reset state the bootloader leaves. */
static inline void port_application(void)
{
    struct hal *h = &hal_stm32;
    memset(h, 0, sizeof *h);
    port_image = PORT_APP;
    gpio_init();
    clock_init(h);
    clock_tick_start(h);
    uart_init(h);
    motor_init(h, &board_arm);
    servo_init(&port_servo, &board_arm, h);
    uart_start(h, &port_servo);
}

/* The main loop for ticks, a pass costing 5 us (the core's own instructions, which the
 * models do not count). Returns 0, or why the code stopped (enum model_exit: a reset). */
static inline int port_loop_for(uint64_t ticks)
{
    uint64_t end = model.now + ticks;
    int why = model_catch(port_stopped);
    if (why)
        return why;
    while (model.now < end) {
        servo_poll(&port_servo);
        model_run(MODEL_US(5));
    }
    model.exit = NULL;
    return 0;
}

/* The host sends bytes at baud (from now, or once the bus is free); returns the tick its
 * last stop bit ends. */
static inline uint64_t port_host_send(const uint8_t *f, uint32_t n, uint32_t baud)
{
    model_wire_send(f, n, baud);
    return model.usart.wire_free;
}

/* Run the main loop until the servo has sent n bytes more than from (or ticks pass); the
 * bytes into out. Returns 0, or why the code stopped. */
static inline int port_await(uint32_t from, uint32_t n, uint8_t *out, uint64_t ticks)
{
    uint64_t end = model.now + ticks;
    int why = 0;
    while (model.usart.tx_len < from + n && model.now < end && why == 0)
        why = port_loop_for(MODEL_US(500));
    for (uint32_t i = 0; i < n && from + i < model.usart.tx_len; i++)
        out[i] = model.usart.tx[from + i].byte;
    return why;
}

static inline void port_assert_answer(uint32_t from, const uint8_t *want, uint32_t n)
{
    assert_int_equal(model.usart.tx_len - from, n);
    for (uint32_t i = 0; i < n; i++) {
        assert_int_equal(model.usart.tx[from + i].byte, want[i]);
        assert_true(model.usart.tx[from + i].de_all_along);
    }
}

/* The first edge of the driver enable to state at or after tick t. */
static inline uint64_t port_de_edge_after(uint64_t t, enum model_pin state)
{
    for (uint32_t i = 0; i < model.gpio.edges; i++)
        if (model.gpio.edge[i].at >= t && model.gpio.edge[i].state == state)
            return model.gpio.edge[i].at;
    return MODEL_NEVER;
}

#endif
