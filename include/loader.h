/* loader.h - update mode: what runs when the application slot holds no valid image.
 * It listens at the stored ID and baud (read through the persistent store, never
 * written) and answers only the §10 update frames; the motor is never driven. The
 * STM32 bootloader runs it; on the host, servo_power_on() does when boot_install()
 * finds no valid application. Its main loop is servo_poll(), as the application's;
 * interrupt side: servo_rx_isr(). */
#ifndef LOADER_H
#define LOADER_H

#include <stdbool.h>
#include <stdint.h>

struct board;
struct frame;
struct hal;
struct servo;

/* The loader's part of struct servo, set by loader.c alone, read through the two calls
 * below (servo.c's loop, the host's node model). */
struct loader {
    uint8_t running;     /* update mode (loader_init), not the application */
    uint8_t restart_due; /* a verified update: restart once its answer has left the wire */
};

static inline bool loader_running(const struct loader *l)
{
    return l->running != 0u;
}

static inline bool loader_restart_due(const struct loader *l)
{
    return l->restart_due != 0u;
}

/* The ID, baud code (register 4) and return delay update mode listens with: read
 * through the store without the register table (store_read; the bootloader has no room
 * for the table), each the stored value if there is a valid one, else the factory one.
 * test_store checks after every simulated power cut that they equal what servo_init()
 * puts in force. */
struct loader_settings {
    uint8_t id, baud_code, delay;
};
void loader_settings(struct hal *hal, const struct board *b, struct loader_settings *out);

/* Power-up in update mode: the stored ID, baud and return delay in force, receiver
 * empty. Reads the flash, never writes it. */
void loader_init(struct servo *s, const struct board *b, struct hal *hal);

/* Answer a §10 frame if it is addressed to this servo: run the session (update.h),
 * schedule the answer (always, ERR 0, after the return delay), and on a verified image
 * mark the restart due (servo_poll restarts once the answer is out). Returns the enum
 * update_outcome. Shared by update mode and the application's dispatcher. */
uint8_t loader_update_frame(struct servo *s, const struct frame *f);

#endif
