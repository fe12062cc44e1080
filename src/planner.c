/* planner.c - one-tick trapezoidal planner (see planner.h). */
#include "planner.h"

/* Floor of the square root of a 64-bit value, bit by bit (no division, no float). */
static uint64_t isqrt64(uint64_t v)
{
    uint64_t res = 0, bit = (uint64_t)1 << 62;
    while (bit > v)
        bit >>= 2;
    while (bit) {
        if (v >= res + bit) {
            v -= res + bit;
            res = (res >> 1) + bit;
        } else {
            res >>= 1;
        }
        bit >>= 2;
    }
    return res;
}

/* Braking from speed v at dec per tick covers T(v) = v + (v - dec) + ... while positive
 * (the first term is the tick being planned). With n = floor(v / dec),
 * T(v) = (n + 1) v - dec n (n + 1) / 2, so the largest v with T(v) <= dist follows from
 * the largest n with dec n (n + 1) / 2 <= dist. */
/* dec n (n + 1) / 2: the distance that braking n ticks at dec gives up against keeping
 * the speed (the sum dec + 2 dec + ... + n dec). Not inlined: one copy of the 64-bit
 * product for its three uses is 56 B smaller in the image. */
__attribute__((noinline)) static uint64_t brake_loss(uint64_t dec, uint64_t n)
{
    return dec * n * (n + 1u) / 2u;
}

/* Not inlined: one copy for its callers, smaller under -flto (measured). */
__attribute__((noinline)) int32_t planner_brake_speed(int64_t dist, int32_t dec)
{
    if (dist <= 0)
        return 0;
    uint64_t d = (uint64_t)dist, a = (uint64_t)dec;
    uint64_t q = d / a;
    if (q > ((uint64_t)1 << 60))
        return INT32_MAX;
    uint64_t n = (isqrt64(8u * q + 1u) - 1u) / 2u; /* n (n + 1) / 2 <= q */
    while (brake_loss(a, n + 1u) <= d)
        n++;
    while (n && brake_loss(a, n) > d)
        n--;
    uint64_t v = (d + brake_loss(a, n)) / (n + 1u);
    return v > INT32_MAX ? INT32_MAX : (int32_t)v;
}

/* Not inlined: one copy for its callers, smaller under -flto (measured). */
__attribute__((noinline)) int64_t planner_stop_distance(int32_t v, int32_t dec)
{
    if (v <= 0)
        return 0;
    uint64_t n = (uint64_t)v / (uint64_t)dec; /* T(v) = (n + 1) v - dec n (n + 1) / 2 */
    return (int64_t)((n + 1u) * (uint64_t)v - brake_loss((uint64_t)dec, n));
}

/* Move the velocity toward want, by at most acc when speeding up and dec when slowing
 * down (a reversal slows to zero first). */
static int32_t ramp(int32_t vel, int32_t want, const struct plan_limits *lim)
{
    if (vel == want)
        return want;
    bool up = vel > 0 ? want > vel : vel < 0 ? want < vel : true; /* away from zero */
    if (vel > 0 && want < 0) {
        int32_t v = vel - lim->dec;
        return v < 0 ? 0 : v;
    }
    if (vel < 0 && want > 0) {
        int32_t v = vel + lim->dec;
        return v > 0 ? 0 : v;
    }
    int32_t step = up ? lim->acc : lim->dec;
    if (want > vel)
        return want - vel > step ? vel + step : want;
    return vel - want > step ? vel - step : want;
}

bool planner_step_to(struct plan *p, int64_t target, const struct plan_limits *lim)
{
    int64_t err = target - p->pos;
    if (err == 0 && p->vel == 0)
        return true;
    int64_t dist = err < 0 ? -err : err;
    int32_t allow = planner_brake_speed(dist, lim->dec);
    int32_t speed = allow < lim->vmax ? allow : lim->vmax;
    int32_t want = err < 0 ? -speed : speed;
    p->vel = ramp(p->vel, want, lim);
    p->pos += p->vel;
    return p->pos == target && p->vel == 0;
}

void planner_step_speed(struct plan *p, int32_t vel_target, const struct plan_limits *lim)
{
    p->vel = ramp(p->vel, vel_target, lim);
    p->pos += p->vel;
}
