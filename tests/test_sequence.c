/* test_sequence.c - trajectory sequencing (src/sequence.c) with the real planner: the
 * reference passes every point of a run in one direction without stopping, at the speed
 * of the point it heads for, comes to rest exactly on each reversal point and on the
 * last one, and nothing else. Links sequence.c, scale.c and planner.c only. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include <cmocka.h>

#include "planner.h"
#include "sequence.h"

static const struct sequence_frame frame = {{16384, 1}, -777}; /* 0.1 deg units, a zero */

static int64_t pos_of(uint16_t units)
{
    return (frame.zero + scale_units_to_counts(frame.sc, units)) * PLANNER_ONE;
}

static struct plan_limits limits_for(uint16_t speed)
{
    struct plan_limits lim;
    lim.vmax = scale_speed_q24(frame.sc, speed);
    lim.acc = lim.dec = scale_accel_q24(frame.sc.cpr, 50, lim.vmax);
    return lim;
}

/* Run the trajectory from `from`; record where the reference rested. */
static int run(const struct traj *t, int64_t from, int64_t *rests, int max_rests)
{
    struct sequence q;
    struct plan p = {from, 0};
    int64_t target;
    sequence_start(&q, t, &frame, p.pos, &target);
    struct plan_limits lim = limits_for(sequence_speed(&q, t));
    int n = 0;
    for (int tick = 0; tick < 2000000; tick++) {
        bool rest = planner_step_to(&p, target, &lim);
        if (rest && (n == 0 || rests[n - 1] != p.pos)) {
            assert_true(n < max_rests);
            rests[n++] = p.pos;
        }
        switch (sequence_step(&q, t, &frame, &p, rest, &target)) {
        case SEQ_NEW_SPEED:
        case SEQ_NEW_SEGMENT:
            lim = limits_for(sequence_speed(&q, t));
            break;
        case SEQ_DONE:
            return n;
        default:
            break;
        }
    }
    fail_msg("trajectory never ended");
    return n;
}

static void rests_on_reversals_and_the_last_point_only(void **state)
{
    (void)state;
    /* up 100 -> 300 -> 500, back to 200, up to 250: rests at 500, 200, 250 */
    struct traj t = {.count = 5};
    const uint16_t a[] = {100, 300, 500, 200, 250}, v[] = {200, 400, 300, 600, 100};
    for (uint8_t i = 0; i < t.count; i++)
        t.pt[i] = (struct traj_point){a[i], v[i]};
    int64_t rests[8];
    int n = run(&t, pos_of(0), rests, 8);
    assert_int_equal(n, 3);
    assert_true(rests[0] == pos_of(500));
    assert_true(rests[1] == pos_of(200));
    assert_true(rests[2] == pos_of(250));
}

static void first_point_behind_the_start_is_a_reversal(void **state)
{
    (void)state;
    /* From 400 (relative to the zero): down to 300, then up to 600: rest at 300 first.
     * (The zero is not 0: the start and the points must be compared from one origin.) */
    struct traj t = {.count = 2};
    t.pt[0] = (struct traj_point){300, 300};
    t.pt[1] = (struct traj_point){600, 300};
    int64_t rests[4];
    int n = run(&t, pos_of(400), rests, 4);
    assert_int_equal(n, 2);
    assert_true(rests[0] == pos_of(300));
    assert_true(rests[1] == pos_of(600));
}

static void each_leg_runs_at_its_points_speed(void **state)
{
    (void)state;
    /* 0 -> 1000 -> 2000 in one direction: the first leg at 100/s, the second at 900/s. */
    struct traj t = {.count = 2};
    t.pt[0] = (struct traj_point){1000, 100};
    t.pt[1] = (struct traj_point){2000, 900};
    struct sequence q;
    struct plan p = {pos_of(0), 0};
    int64_t target;
    sequence_start(&q, &t, &frame, p.pos, &target);
    assert_true(target == pos_of(2000)); /* one run: it rests at the end only */
    struct plan_limits lim = limits_for(sequence_speed(&q, &t));
    int32_t peak1 = 0, peak2 = 0;
    for (int tick = 0; tick < 100000; tick++) {
        bool rest = planner_step_to(&p, target, &lim);
        if (p.pos < pos_of(1000))
            peak1 = abs(p.vel) > peak1 ? abs(p.vel) : peak1;
        else
            peak2 = abs(p.vel) > peak2 ? abs(p.vel) : peak2;
        uint8_t ev = sequence_step(&q, &t, &frame, &p, rest, &target);
        if (ev == SEQ_NEW_SPEED)
            lim = limits_for(sequence_speed(&q, &t));
        if (ev == SEQ_DONE)
            break;
    }
    assert_true(peak1 <= limits_for(100).vmax);
    assert_true(peak2 > limits_for(100).vmax * 5); /* the second leg speeds up */
    assert_true(p.pos == pos_of(2000) && p.vel == 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(rests_on_reversals_and_the_last_point_only),
        cmocka_unit_test(first_point_behind_the_start_is_a_reversal),
        cmocka_unit_test(each_leg_runs_at_its_points_speed),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
