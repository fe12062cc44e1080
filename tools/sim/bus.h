/* bus.h - the servos of servo-sim in real time: each a node (hal/host/node.h) whose clock
 * (hal.now_us) is CLOCK_MONOTONIC in microseconds, plus a configuration window before it.
 *
 * - The bytes a client sends are fed to every servo through servo_rx_isr() when they
 *   arrive (TCP has no baud rate, so a request takes no wire time). Every servo hears
 *   every host byte whatever its register 4 says.
 * - A servo's answer is paced at its own baud: each byte goes to the client once its stop
 *   bit has ended (the host HAL's tx log gives the times). Bytes of several servos are
 *   merged in time order (node_tx_next). Servos do not hear each other.
 * - The loop wakes at least every BUS_TICK_US. When it wakes late (a loaded host), each
 *   servo catches up in steps of BUS_TICK_US of its own clock, and an answer that fell
 *   due meanwhile starts at its due time, as the MCU would have run them.
 * - The motor and the photo switches of each servo are the host HAL's plant
 *   (hal_host_attach_board()), integrated up to the real clock. */
#ifndef BUS_H
#define BUS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "node.h"
#include "state.h"

#define BUS_TICK_US 500u /* main-loop period when nothing is due sooner */

struct sim_servo {
    struct node node;
    uint8_t arg_id; /* as given on the command line; names the state file */
    struct state_file state;
};

/* Add a servo of board b: its state file first (with state_dir), then power-up; a new
 * servo (blank flash) gets arg_id the one way (node_set_id), in virtual time before the
 * real clock starts. Call before bus_start(). */
void bus_add(uint8_t arg_id, const struct board *b, const char *state_dir);

/* The real clock starts: every servo's clock is set to it. */
void bus_start(void);

unsigned bus_count(void);
const struct sim_servo *bus_servo(unsigned i);

/* Microseconds of the servos' clock now (wraps at 2^32 like the HAL). */
uint32_t bus_now(void);

/* Bring every servo up to now. */
void bus_step(uint32_t now);

/* Bytes a client sent, arriving at now: every servo hears them. */
void bus_host_bytes(const uint8_t *in, size_t n, uint32_t now);

/* Servo bytes whose stop bit has ended by now, oldest first, into out (at most max;
 * the rest is dropped, as it is with no client: pass max 0). Returns the count. */
size_t bus_output(uint32_t now, uint8_t *out, size_t max);

/* Microseconds until something is due: a byte's end, an answer's start. */
uint32_t bus_next_wake(uint32_t now);

void bus_free(void);

#endif
