/* vbus.h - a virtual half-duplex bus in virtual time: a host and several host-built
 * servos, each with its own host HAL. Every byte on the wire has a start and an end time
 * and a baud rate; a device hears a byte only at its own baud; bytes of two talkers that
 * overlap in time are counted as a collision. Used by the replay tests, the demo and the
 * benchmarks. Its servos are node.h's, as servo-sim's are; servo-sim runs them in real
 * time on a line modelled bit by bit (wire.h), where overlapping bytes garble. */
#ifndef VBUS_H
#define VBUS_H

#include <stdbool.h>
#include <stdint.h>

#include "hal_host.h"
#include "node.h"
#include "servo.h"

#define VBUS_NODES_MAX 8u
#define VBUS_WIRE_MAX 16384u /* power of two: bytes kept on the wire log */
#define VBUS_HOST (-1)

struct vbus_byte {
    uint32_t start_us, end_us, baud;
    uint8_t byte;
    int8_t src; /* VBUS_HOST or a node index */
};

struct vbus {
    uint32_t now_us;
    uint32_t step_us;   /* main-loop period of every servo */
    uint32_t host_baud;
    uint32_t wire_len;  /* bytes ever put on the wire */
    uint32_t delivered; /* bytes whose end has passed and that were handed to receivers */
    uint32_t host_read; /* next wire byte the host has not looked at */
    uint32_t last_host_end_us;
    uint32_t wire_end_us; /* end of the latest byte on the wire */
    int8_t wire_end_src;
    uint32_t collisions;
    uint8_t nodes;
    struct node node[VBUS_NODES_MAX]; /* node.h: log_seen counts what is on the wire */
    struct vbus_byte wire[VBUS_WIRE_MAX];
};

/* Empty bus at HAL_HOST_CLOCK_START (10 s before the clock wraps), host at 9600 baud, 1 us main-loop period. */
void vbus_init(struct vbus *b);

/* Power up a servo of board bd on the bus, its factory image in the application slot.
 * A non-zero id other than the factory ID was configured earlier, the one way
 * (node_set_id(): a WRITE of register 3 in the NODE_SET_ID_US before now, so the store
 * holds it and a power cycle keeps it). Returns its node index. */
uint8_t vbus_add(struct vbus *b, const struct board *bd, uint8_t id);

/* Power cycle node i (also what its hal_restart() leads to): the flash stays, the
 * bootloader's decision runs (node_restart). */
void vbus_power_cycle(struct vbus *b, uint8_t i);

/* The host puts n bytes on the wire back to back, starting now, at host_baud; the bus
 * runs until the last one has ended. */
void vbus_host_send(struct vbus *b, const uint8_t *bytes, uint32_t n);

/* The same, but the bus does not run: returns when the last byte will have ended (now
 * if n is 0). A test that steps the bus itself (vbus_run_until) watches it go by. */
uint32_t vbus_host_queue(struct vbus *b, const uint8_t *bytes, uint32_t n);

/* Run every servo's main loop (and deliver wire bytes) until t_us. */
void vbus_run_until(struct vbus *b, uint32_t t_us);

/* Servo bytes on the wire that the host has not looked at yet. */
uint32_t vbus_host_pending(const struct vbus *b);

/* Next servo byte on the wire (call only when vbus_host_pending() > 0). */
const struct vbus_byte *vbus_host_next(struct vbus *b);

/* The wire byte with index i (i < wire_len, not older than VBUS_WIRE_MAX). */
const struct vbus_byte *vbus_wire(const struct vbus *b, uint32_t i);

#endif
