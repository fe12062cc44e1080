/* motion.h - the narrow interface from the bus side (dispatch) to the motion and safety
 * layer. The dispatcher decodes and validates every instruction; what it hands over here
 * is already well-formed. Every function runs in the main loop. */
#ifndef MOTION_H
#define MOTION_H

#include <stdbool.h>
#include <stdint.h>

#include "control.h"
#include "homing.h"
#include "planner.h"
#include "sequence.h"

struct servo;

#define MOTION_TICK_US 1000u /* control tick: 1 kHz */

enum motion_mode {
    MOTION_OFF,   /* torque off (power-up, speed 0, sleep) */
    MOTION_HOLD,  /* hold the reference position (after a move, brake) */
    MOTION_MOVE,  /* trapezoidal move to target */
    MOTION_SPEED, /* speed mode */
    MOTION_TRAJ,  /* running the stored trajectory */
    MOTION_STOP,  /* controlled stop (heartbeat), then hold */
    MOTION_HOME,  /* homing (§9) */
};

/* The status nibble of register 24. */
enum homing_status { HOMING_NEVER, HOMING_RUNNING, HOMING_DONE, HOMING_FAILED };

/* State of the motion layer of one servo: the mode and the planned reference are its
 * own; the controller, homing and trajectory sequencing keep theirs in their structs. */
struct motion {
    struct plan plan;        /* reference (counts x 2^24) */
    struct plan_limits lim;  /* of the running move */
    uint16_t cruise;         /* its cruise speed, units/s (lim.vmax before the cap) */
    int64_t target;          /* move target, counts x 2^24 */
    int32_t speed_target;    /* speed mode velocity, counts/tick x 2^24 */
    int64_t zero;            /* counts at position 0 */
    uint32_t tick_us;        /* time of the last control tick */
    uint8_t mode;            /* enum motion_mode */
    uint8_t referenced;      /* homing succeeded: the limits are the measured travel */
    struct control ctl;      /* control.h */
    struct homing home;      /* homing.h */
    struct sequence seq;     /* sequence.h */
};

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

/* May a host write of data[0..n) to addr run now? False refuses the whole write with an
 * instruction error: a motion command while a protection unload is latched or (register
 * 49) before homing, the angle limits while homing runs (it measures them), or clearing
 * an unload whose condition persists. */
bool motion_write_allowed(const struct servo *s, uint8_t addr, const uint8_t *data, uint8_t n);

/* The registers [addr, addr + n) were written by the host and hold their new values. */
void motion_on_write(struct servo *s, uint8_t addr, uint8_t n);

/* START/END (§4.6): what is 1 or 2 and the servo is in position mode. Returns 0 or
 * ERR_INSTRUCTION (also while homing runs: it sets the zero and the limits). */
uint8_t motion_start_end(struct servo *s, uint8_t what);

/* TRAJECTORY ACTION (§4.7): the stored trajectory is not empty. Returns 0 or
 * ERR_INSTRUCTION. */
uint8_t motion_traj_action(struct servo *s);

/* CUSTOM MOVE (§4.8): may it run now? 0 or ERR_INSTRUCTION (a speed of 0 always may). */
uint8_t motion_custom_allowed(const struct servo *s, const struct custom_move *m);

/* CUSTOM MOVE, allowed, its ramps already in the registers. */
void motion_custom_move(struct servo *s, const struct custom_move *m);

/* Torque off at once and stay off until the next motion command (a firmware update). */
void motion_torque_off(struct servo *s);

/* The present position in the unit of register 13 in force (registers 36 and 40). */
int32_t motion_position(const struct servo *s);

/* RESET: stop everything and forget the homing reference. */
void motion_reset(struct servo *s);

/* Write the present-state registers (§5.1) from the sensors and the motion state: every
 * control tick, and after every dispatched packet, so the next READ already sees what a
 * command changed (moving 1 as soon as a move is commanded, not a tick later). */
void motion_report(struct servo *s);

/* Main loop: run the control ticks that are due at now_us (1 kHz). */
void motion_poll(struct servo *s, uint32_t now_us);

#endif
