/* motion.h - the narrow interface from the bus side (dispatch) to the motion and safety
 * layer. The dispatcher decodes and validates every instruction; what it hands over here
 * is already well-formed. Every function runs in the main loop. */
#ifndef MOTION_H
#define MOTION_H

#include <stdbool.h>
#include <stdint.h>

struct servo;

/* CUSTOM MOVE (PROTOCOL.md §4.8), decoded. */
struct custom_move {
    uint8_t absolute;  /* 0: relative (sub 0x01), 1: absolute (sub 0x02) */
    uint8_t has_ramps; /* acc/dec given (and written into the registers) */
    uint16_t target;   /* absolute position, or relative magnitude */
    uint16_t speed;    /* register 32 format: bit 15 direction (relative only) */
    uint8_t acc, dec;
};

/* Bring the motion layer up: motor off, present position read, nothing moves (rule 1). */
void motion_init(struct servo *s);

/* May a host write to [addr, addr + n) run now? False refuses the whole write with an
 * instruction error (e.g. a motion command while a protection unload is latched). */
bool motion_write_allowed(const struct servo *s, uint8_t addr, uint8_t n);

/* The registers [addr, addr + n) were written by the host and hold their new values. */
void motion_on_write(struct servo *s, uint8_t addr, uint8_t n);

/* START/END (§4.6): what is 1 or 2 and the servo is in position mode. Returns 0 or
 * ERR_INSTRUCTION. */
uint8_t motion_start_end(struct servo *s, uint8_t what);

/* TRAJECTORY ACTION (§4.7): the stored trajectory is not empty. Returns 0 or
 * ERR_INSTRUCTION. */
uint8_t motion_traj_action(struct servo *s);

/* CUSTOM MOVE (§4.8). Returns 0 or ERR_INSTRUCTION. */
uint8_t motion_custom_move(struct servo *s, const struct custom_move *m);

/* RESET: stop everything and forget the homing reference. */
void motion_reset(struct servo *s);

#endif
