/* scale.h - position, speed and acceleration between the register units of §5 and the
 * motion layer's encoder counts (positions) and counts per control tick x 2^24 (speeds,
 * accelerations). Pure integer arithmetic, rounded, no state. */
#ifndef SCALE_H
#define SCALE_H

#include <stdint.h>

#define SCALE_TICKS_PER_S 1000   /* the control tick: 1 kHz (motion.h MOTION_TICK_US) */
#define SCALE_MAX_SPEED_DPS 1080 /* what the reference may ask for, degree/s at the output */

/* Counts per output revolution and register 13 (0.1 degree per position unit). */
struct scale {
    uint32_t cpr;
    uint8_t resolution;
};

int64_t scale_units_to_counts(struct scale sc, int32_t units);
int32_t scale_counts_to_units(struct scale sc, int64_t counts);

/* Speed magnitude in units/s to counts/tick x 2^24, capped at SCALE_MAX_SPEED_DPS. */
int32_t scale_speed_q24(struct scale sc, uint16_t units_per_s);

/* Degree/s to counts/tick x 2^24 (homing's fixed speed). */
int32_t scale_dps_q24(uint32_t cpr, uint16_t dps);

/* An acceleration register (10 degree/s^2; 0 = no ramp: full speed in one tick) to
 * counts/tick^2 x 2^24, at least 1. */
int32_t scale_accel_q24(uint32_t cpr, uint8_t reg, int32_t vmax);

/* A measured speed in counts/tick x 2^8 to units/s, rounded, within int16_t (register 38). */
int16_t scale_speed_units(struct scale sc, int32_t vel_q8);

#endif
