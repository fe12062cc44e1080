/* motion.h - the motion layer of one servo (PROTOCOL.md §6, §9): its state, its bring-up,
 * the control tick and the present registers. What the host's commands mean to it is
 * command.h's. Every function runs in the main loop. */
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
enum homing_status {
    HOMING_STATUS_NEVER,
    HOMING_STATUS_RUNNING,
    HOMING_STATUS_DONE,
    HOMING_STATUS_FAILED,
};

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
    uint8_t stop_within;     /* MOTION_STOP ends within the limits (not the heartbeat's) */
    struct control ctl;      /* control.h */
    struct homing home;      /* homing.h */
    struct sequence seq;     /* sequence.h */
};

/* Bring the motion layer up: motor off, present position read, nothing moves (rule 1). */
void motion_init(struct servo *s);

/* Write the present-state registers (§5.1) from the sensors and the motion state: every
 * control tick, and after every dispatched packet, so the next READ already sees what a
 * command changed (moving 1 as soon as a move is commanded, not a tick later). */
void motion_report(struct servo *s);

/* Main loop: run the control ticks that are due at now_us (1 kHz). */
void motion_poll(struct servo *s, uint32_t now_us);

#endif
