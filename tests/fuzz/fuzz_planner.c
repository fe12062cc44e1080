/* fuzz_planner.c - the motion planner (include/planner.h) from arbitrary states under
 * arbitrary commands: position, velocity and limits to start from, then per tick a new
 * goal, a speed-mode target or new limits, as often as every tick.
 *
 * Input (all little-endian), read until it runs out (missing bytes read as 0):
 *   start:  position P, velocity V, limits L (vmax, acc, dec), goal P
 *   then commands, one byte c each, applied for (c >> 3) + 1 ticks:
 *     c & 3 = 0  keep going          1  new goal: the present position + a signed amount A
 *             2  new goal P           3  speed mode, target velocity V
 *     c & 4      new limits L first
 *   P: 2 bytes mantissa (signed) and a shift byte: m << (s % 46), so |P| <= 2^60
 *   A: the same, the shift s % 40
 *   V: 2 bytes mantissa (signed) and a shift byte: m << (s % 17), within +-(2^31 - 1)
 *   L: three times 2 bytes mantissa m and a shift byte: (m + 1) << (s % 32), at most
 *      2^31 - 1 (a limit is never 0)
 * At most MAX_TICKS ticks. Then, if a goal is in force, the planner runs on toward it.
 *
 * Invariants (abort on violation):
 *   1. acceleration never over its limit: the velocity is what the position moved by in
 *      the tick; it gains at most acc per tick in magnitude and loses at most dec (a
 *      reversal: it loses its old magnitude, at most dec, and gains the new one, at most
 *      acc);
 *   2. exact landing: with the goal and limits left alone, the reference rests on the
 *      goal (position equal, velocity 0) within a bound worked out from the state (twice
 *      the time to stop and then cover the distance with the smaller of acc and dec at
 *      most vmax, plus 16 ticks), says so, and stays there; checked whenever that bound
 *      is at most LAND_TICKS;
 *   3. no overflow: UBSan (signed and, for planner.c, unsigned arithmetic and implicit
 *      conversions under libFuzzer) aborts on any. */
#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "fuzz.h"
#include "planner.h"

#define MAX_TICKS 256u
#define LAND_TICKS 256.0

const char fuzz_target_name[] = "fuzz_planner";

static int16_t get_s16(struct fuzz_reader *r)
{
    uint16_t lo = fuzz_get8(r);
    return (int16_t)(uint16_t)(lo | (uint16_t)(fuzz_get8(r) << 8));
}

static int64_t get_pos(struct fuzz_reader *r, unsigned shifts)
{
    int64_t m = get_s16(r);
    unsigned s = fuzz_get8(r) % shifts;
    return m * ((int64_t)1 << s);
}

static int32_t get_vel(struct fuzz_reader *r)
{
    int64_t v = get_pos(r, 17u); /* |m| <= 2^15, so |v| <= 2^31 */
    if (v > INT32_MAX)
        v = INT32_MAX;
    if (v < -INT32_MAX)
        v = -INT32_MAX;
    return (int32_t)v;
}

static int32_t get_limit(struct fuzz_reader *r)
{
    uint64_t m = (uint16_t)get_s16(r);
    uint64_t v = (m + 1u) << (fuzz_get8(r) % 32u);
    return v > INT32_MAX ? INT32_MAX : (int32_t)v;
}

static void get_limits(struct fuzz_reader *r, struct plan_limits *lim)
{
    lim->vmax = get_limit(r);
    lim->acc = get_limit(r);
    lim->dec = get_limit(r);
}

static int64_t mag(int64_t v)
{
    return v < 0 ? -v : v;
}

/* Invariant 1 for one tick from velocity v0 (position p0) to the plan p. */
static void check_tick(int64_t p0, int32_t v0, const struct plan *p, const struct plan_limits *lim)
{
    FUZZ_CHECK(p->pos - p0 == p->vel);
    int64_t a = v0, b = p->vel;
    if ((a > 0 && b < 0) || (a < 0 && b > 0)) { /* reversal: through 0 */
        FUZZ_CHECK(mag(a) <= lim->dec);
        FUZZ_CHECK(mag(b) <= lim->acc);
    } else if (mag(b) > mag(a)) {
        FUZZ_CHECK(mag(b) - mag(a) <= lim->acc);
    } else {
        FUZZ_CHECK(mag(a) - mag(b) <= lim->dec);
    }
}

static bool step_to(struct plan *p, int64_t goal, const struct plan_limits *lim)
{
    int64_t p0 = p->pos;
    int32_t v0 = p->vel;
    bool done = planner_step_to(p, goal, lim);
    check_tick(p0, v0, p, lim);
    FUZZ_CHECK(done == (p->pos == goal && p->vel == 0));
    return done;
}

/* Ticks within which a move from p to goal under lim must land (invariant 2). */
static double land_bound(const struct plan *p, int64_t goal, const struct plan_limits *lim)
{
    double v = fabs((double)p->vel), dec = lim->dec, vmax = lim->vmax;
    double a = lim->acc < lim->dec ? lim->acc : lim->dec;
    double t_stop = v / dec + 1.0;
    double stop_dist = v * (t_stop + 1.0);
    double d = fabs((double)(goal - p->pos)) + stop_dist; /* exact difference first */
    double t_move = d <= vmax * vmax / a ? 2.0 * sqrt(d / a) : d / vmax + vmax / a;
    return 2.0 * (t_stop + t_move + 2.0) + 16.0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_progress();
    struct fuzz_reader r = {data, size};
    struct plan p;
    struct plan_limits lim;
    p.pos = get_pos(&r, 46u);
    p.vel = get_vel(&r);
    get_limits(&r, &lim);
    int64_t goal = get_pos(&r, 46u);
    bool speed_mode = false;
    int32_t speed = 0;

    for (unsigned ticks = 0; r.left && ticks < MAX_TICKS;) {
        uint8_t c = fuzz_get8(&r);
        if (c & 4u)
            get_limits(&r, &lim);
        switch (c & 3u) {
        case 1:
            goal = p.pos + get_pos(&r, 40u);
            speed_mode = false;
            break;
        case 2:
            goal = get_pos(&r, 46u);
            speed_mode = false;
            break;
        case 3:
            speed = get_vel(&r);
            speed_mode = true;
            break;
        default:
            break;
        }
        for (unsigned n = (c >> 3) + 1u; n && ticks < MAX_TICKS; n--, ticks++) {
            if (speed_mode) {
                int64_t p0 = p.pos;
                int32_t v0 = p.vel;
                planner_step_speed(&p, speed, &lim);
                check_tick(p0, v0, &p, &lim);
            } else {
                (void)step_to(&p, goal, &lim);
            }
        }
    }
    if (speed_mode)
        return 0;
    double bound = land_bound(&p, goal, &lim);
    if (bound > LAND_TICKS)
        return 0; /* too long a move to follow here; the bound was never reached so far */
    unsigned t = 0;
    while (!step_to(&p, goal, &lim)) {
        t++;
        if (t > (unsigned)bound) {
            fprintf(stderr, "fuzz_planner: no landing within %u ticks: pos %lld vel %d goal %lld\n",
                    t, (long long)p.pos, p.vel, (long long)goal);
            FUZZ_CHECK(!"landed within the bound");
        }
    }
    for (int i = 0; i < 3; i++) /* and stays */
        FUZZ_CHECK(step_to(&p, goal, &lim));
    return 0;
}
