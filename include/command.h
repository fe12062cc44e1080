/* command.h - what the host's commands mean to the motor (PROTOCOL.md §4.6-§4.8, §5,
 * §6): the narrow interface from the bus side (dispatch.c, write.c) to the motion layer.
 * The dispatcher decodes and validates every instruction; what it hands over here is
 * already well-formed. Every function runs in the main loop. */
#ifndef COMMAND_H
#define COMMAND_H

#include <stdbool.h>
#include <stdint.h>

#include "regs.h"

struct servo;

/* CUSTOM MOVE (PROTOCOL.md §4.8), decoded. */
struct custom_move {
    uint8_t absolute;  /* 0: relative (sub 0x01), 1: absolute (sub 0x02) */
    uint8_t has_ramps; /* acc/dec given (and written into the registers) */
    uint16_t target;   /* absolute position, or relative magnitude */
    uint16_t speed;    /* register 32 format: bit 15 direction (relative only) */
    uint8_t acc, dec;
};

/* May a motion command start now: not braked, asleep or unloaded, and on a motor with
 * photo switches homed (register 49 aside, which only speed mode honours)? */
bool command_may_move(const struct servo *s);

/* May this register write run? 0, or ERR_INSTRUCTION to refuse all of it: a motion
 * command while a protection unload is latched or (register 49) before homing, or the
 * angle limits while homing runs (it measures them). */
uint8_t command_write_check(const struct servo *s, const struct reg_write *w);

/* The registers of w were written by the host and hold their new values: act on them. */
void command_written(struct servo *s, const struct reg_write *w);

/* START/END (§4.6): what is 1 or 2 and the servo is in position mode. Returns 0 or
 * ERR_INSTRUCTION (while homing runs: it sets the zero and the limits; and an END that
 * would leave both limits 0, which would make the joint a wheel: §6.2). */
uint8_t command_start_end(struct servo *s, uint8_t what);

/* TRAJECTORY ACTION (§4.7), allowed, the stored trajectory not empty. */
void command_traj_action(struct servo *s);

/* TRAJECTORY WRITE (§4.7) replaced the stored points: a trajectory running on the old
 * ones stops (docs/decisions.md), so the running path is never spliced. */
void command_traj_written(struct servo *s);

/* CUSTOM MOVE (§4.8), allowed: its ramps go into the ramp registers, then it moves. */
void command_custom_move(struct servo *s, const struct custom_move *m);

/* Torque off at once and stay off until the next motion command (a firmware update). */
void command_coast(struct servo *s);

/* RESET: stop everything and forget the homing reference. */
void command_reset(struct servo *s);

#endif
