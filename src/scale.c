/* scale.c - register units to counts and back (scale.h). */
#include "planner.h"
#include "scale.h"

/* num / den (den > 0) rounded half away from zero: the one rounding of every conversion
 * here. Not inlined: one copy of the 64-bit division set-up is smaller in the image. */
__attribute__((noinline)) static int64_t div_round(int64_t num, int64_t den)
{
    return (num + (num >= 0 ? den / 2 : -den / 2)) / den;
}

int64_t scale_units_to_counts(struct scale sc, int32_t units)
{
    return div_round((int64_t)units * sc.resolution * sc.cpr, 3600);
}

int32_t scale_counts_to_units(struct scale sc, int64_t counts)
{
    return (int32_t)div_round(counts * 3600, (int64_t)sc.resolution * sc.cpr);
}

int32_t scale_dps_q24(uint32_t cpr, uint16_t dps)
{
    return (int32_t)(((int64_t)dps * cpr << PLANNER_SHIFT) / ((int64_t)360 * SCALE_TICKS_PER_S));
}

int32_t scale_speed_q24(struct scale sc, uint16_t units_per_s)
{
    int64_t max = scale_dps_q24(sc.cpr, SCALE_MAX_SPEED_DPS);
    int64_t v = ((int64_t)units_per_s * sc.resolution * sc.cpr << PLANNER_SHIFT) /
                ((int64_t)3600 * SCALE_TICKS_PER_S);
    return (int32_t)(v > max ? max : v);
}

int32_t scale_accel_q24(uint32_t cpr, uint8_t reg, int32_t vmax)
{
    if (reg == 0)
        return vmax > 0 ? vmax : 1;
    int64_t a = ((int64_t)reg * 10 * cpr << PLANNER_SHIFT) /
                (360 * (int64_t)SCALE_TICKS_PER_S * SCALE_TICKS_PER_S);
    return a > 0 ? (int32_t)a : 1;
}

int16_t scale_speed_units(struct scale sc, int32_t vel_q8)
{
    int64_t speed = div_round((int64_t)vel_q8 * SCALE_TICKS_PER_S * 3600,
                              (int64_t)256 * sc.resolution * sc.cpr);
    if (speed > INT16_MAX)
        speed = INT16_MAX;
    if (speed < INT16_MIN)
        speed = INT16_MIN;
    return (int16_t)speed;
}
