/* wire_servo.h - one servo on the host HAL, powered up as the MCU does (the bootloader's
 * decision, then the application or update mode) and driven through its wire at 9600
 * baud, the arm's default: the harness test_boot.c and test_update.c share. A restart
 * the servo asks for (an installed update, the watchdog) is a power cycle, counted. */
#ifndef WIRE_SERVO_H
#define WIRE_SERVO_H

#include <stdint.h>

#include "hal_host.h"
#include "servo.h"

#define WIRE_BYTE_US 1042u /* one byte at 9600 baud */

struct wire_servo {
    struct hal hal;
    struct servo s;
    const struct board *board;
    uint32_t resets; /* restarts the servo asked for */
};

static inline void wire_power_on(struct wire_servo *w)
{
    hal_host_reboot(&w->hal);
    servo_power_on(&w->s, w->board, &w->hal);
}

/* A servo fresh from the factory: version SERVO_FW_VERSION in the application slot. */
static inline void wire_factory(struct wire_servo *w)
{
    hal_host_init(&w->hal);
    hal_host_attach_board(&w->hal, w->board);
    hal_host_program_factory(&w->hal, w->board);
    w->resets = 0;
    wire_power_on(w);
}

/* us of time, then one main-loop pass of what runs. */
static inline void wire_step(struct wire_servo *w, uint32_t us)
{
    w->hal.now_us += us;
    servo_step(&w->s);
    if (w->hal.restart_requested) {
        w->resets++;
        wire_power_on(w);
    }
}

/* Put bytes on the wire, then run wait_us in 100 us steps; the answer (up to 64 bytes)
 * in ans, its length returned. */
static inline uint16_t wire_xfer_wait(struct wire_servo *w, const uint8_t *out, uint16_t n,
                                      uint8_t *ans, uint32_t wait_us)
{
    uint32_t seen = w->hal.log_len;
    for (uint16_t i = 0; i < n; i++) {
        w->hal.now_us += WIRE_BYTE_US;
        servo_rx_isr(&w->s, out[i]);
        servo_step(&w->s);
    }
    for (uint32_t t = 0; t < wait_us; t += 100u)
        wire_step(w, 100);
    uint16_t got = 0;
    while (seen < w->hal.log_len && got < 64u)
        ans[got++] = hal_host_tx(&w->hal, seen++)->byte;
    return got;
}

static inline uint16_t wire_xfer(struct wire_servo *w, const uint8_t *out, uint16_t n,
                                 uint8_t *ans)
{
    return wire_xfer_wait(w, out, n, ans, 60000u); /* 8 ms delay + an answer, with margin */
}

#endif
