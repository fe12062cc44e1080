/* motion.h - the narrow interface from the bus side (dispatch) to the motion and safety
 * layer. The dispatcher decodes and validates every instruction; what it hands over here
 * is already well-formed. Every function runs in the main loop. */
#ifndef MOTION_H
#define MOTION_H

#include <stdbool.h>
#include <stdint.h>

#include "planner.h"

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

/* Homing phases and the status nibble of register 24. */
enum homing_phase { HOME_BACKOFF, HOME_SEEK, HOME_REVERSE, HOME_END };
enum homing_status { HOMING_NEVER, HOMING_RUNNING, HOMING_DONE, HOMING_FAILED };

/* State of the motion layer of one servo. */
struct motion {
    struct plan plan;        /* reference (counts x 2^24) */
    struct plan_limits lim;  /* of the running move */
    int64_t target;          /* move target, counts x 2^24 */
    int32_t speed_target;    /* speed mode velocity, counts/tick x 2^24 */
    int64_t counts;          /* measured position, unwrapped */
    int64_t zero;            /* counts at position 0 */
    int32_t raw;             /* last raw sensor reading */
    int32_t vel_q8;          /* measured velocity, counts/tick x 2^8, filtered */
    int8_t vel_rem;          /* the filter's division remainder, carried */
    int32_t integral;        /* position error summed while the reference rests */
    uint32_t tick_us;        /* time of the last control tick */
    int16_t duty;            /* last drive */
    uint8_t mode;            /* enum motion_mode */
    uint8_t traj_next;       /* trajectory: point being approached */
    uint8_t traj_stop;       /* trajectory: last point before a reversal or the end */
    int8_t sign;             /* -1 when register 19 = 2 mirrors the motor (§9) */
    uint8_t referenced;      /* homing succeeded: the limits are the measured travel */
    uint8_t home_phase;      /* enum homing_phase */
    int64_t home_from;       /* counts where the phase began */
    uint8_t sw_raw, sw_count; /* photo switch debouncing */
    int64_t sw_edge;         /* counts where the switches last changed (not debounce-late) */
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
 * 49) before homing, or clearing an unload whose condition persists. */
bool motion_write_allowed(const struct servo *s, uint8_t addr, const uint8_t *data, uint8_t n);

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

/* Torque off at once and stay off until the next motion command (a firmware update). */
void motion_torque_off(struct servo *s);

/* RESET: stop everything and forget the homing reference. */
void motion_reset(struct servo *s);

/* Main loop: run the control ticks that are due at now_us (1 kHz). */
void motion_poll(struct servo *s, uint32_t now_us);

#endif
