/* scale.c - register units to counts and back (scale.h). */
#include "planner.h"
#include "scale.h"

/* num / den (den > 0) rounded half away from zero: the one rounding of every conversion
 * here. Not inlined: one copy of the 64-bit division set-up is smaller in the image.
 * The magnitude is divided unsigned and the sign put back: the same quotient as C's
 * truncating (num +- den / 2) / den, and every 64-bit division of the image is then
 * unsigned, so the signed helper of the run-time library (divmod64.c) is not linked:
 * smaller, and one frame less under the main loop's deepest call. */
__attribute__((noinline)) static int64_t div_round(int64_t num, int64_t den)
{
    uint64_t mag = num < 0 ? 0u - (uint64_t)num : (uint64_t)num;
    int64_t q = (int64_t)((mag + (uint64_t)den / 2u) / (uint64_t)den);
    return num < 0 ? -q : q;
}

int64_t scale_units_to_counts(struct scale sc, int32_t units)
{
    return div_round((int64_t)units * sc.resolution * sc.cpr, 3600);
}

int32_t scale_counts_to_units(struct scale sc, int64_t counts)
{
    return (int32_t)div_round(counts * 3600, (int64_t)sc.resolution * sc.cpr);
}

/* Not inlined: one copy for its callers, smaller under -flto (measured). */
__attribute__((noinline)) int32_t scale_dps_q24(uint32_t cpr, uint16_t dps)
{
    /* Unsigned: both operands are positive (div_round). */
    return (int32_t)(((uint64_t)dps * cpr << PLANNER_SHIFT) / ((uint64_t)360 * SCALE_TICKS_PER_S));
}

int32_t scale_speed_q24(struct scale sc, uint16_t units_per_s)
{
    int64_t max = scale_dps_q24(sc.cpr, SCALE_MAX_SPEED_DPS);
    /* Unsigned: as scale_dps_q24. */
    int64_t v = (int64_t)(((uint64_t)units_per_s * sc.resolution * sc.cpr << PLANNER_SHIFT) /
                          ((uint64_t)3600 * SCALE_TICKS_PER_S));
    return (int32_t)(v > max ? max : v);
}

int32_t scale_accel_q24(uint32_t cpr, uint8_t reg, int32_t vmax)
{
    if (reg == 0)
        return vmax > 0 ? vmax : 1;
    /* Unsigned: as scale_dps_q24. */
    int64_t a = (int64_t)(((uint64_t)reg * 10u * cpr << PLANNER_SHIFT) /
                          ((uint64_t)360 * SCALE_TICKS_PER_S * SCALE_TICKS_PER_S));
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
