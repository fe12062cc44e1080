/* control.h - the sensor side and the position loop of one motor, once per control
 * tick: unwrap the encoder into counts, filter the speed, debounce the photo switches,
 * and turn the planned reference into a duty. Knows nothing of registers or modes:
 * motion.c feeds it and decides when the motor is driven. Main loop only. */
#ifndef CONTROL_H
#define CONTROL_H

#include <stdint.h>

#include "planner.h"

/* counts, vel_q8, duty, switches and sw_edge are the outputs others read; the rest is
 * control.c's own. */
struct control {
    int64_t counts;   /* measured position, unwrapped */
    int32_t raw;      /* last raw sensor reading */
    int32_t vel_q8;   /* measured velocity, counts/tick x 2^8, filtered */
    int8_t vel_rem;   /* the filter's division remainder, carried */
    int32_t integral; /* position error summed while the reference rests */
    int16_t duty;     /* last drive, before the mirror sign */
    int8_t sign;      /* -1 when register 19 = 2 mirrors the motor (§9) */
    uint8_t switches; /* photo switches, debounced (register 48 layout) */
    uint8_t sw_raw, sw_count;
    int64_t sw_edge;  /* counts where the switches last changed (not debounce-late) */
};

/* Counts: a shaft this near a resting reference is there (the integral rests, and the
 * motion layer counts it as settled). */
#define CONTROL_HOLD_BAND 1

/* What bounds the drive: register 12 (0.1 A, 0 = no limit) and the board's duty per A. */
struct control_limits {
    uint8_t current_limit;
    uint16_t duty_per_amp;
};

void control_init(struct control *c, int32_t raw, int8_t sign);

/* One tick's sensor readings: the raw position and the photo switches (bits 0-1). */
void control_measure(struct control *c, int32_t raw, uint8_t switches);

/* The motor is mirrored from now on (register 19): counts change sign. */
void control_mirror(struct control *c);

/* The duty for the reference this tick (per mille, mirror sign not applied); also kept
 * in c->duty. */
int16_t control_duty(struct control *c, const struct plan *ref, const struct control_limits *lim);

/* The drive starts from rest of the loop: nothing summed yet. */
void control_engage(struct control *c);

/* The drive is off: no duty. */
void control_release(struct control *c);

#endif
