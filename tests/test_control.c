/* test_control.c - the sensor side and the position loop (src/control.c) on their own:
 * the encoder unwraps across the raw counter's overflow and the mirror, the speed filter
 * reaches its input exactly (a shaft at rest reads 0: issue 13), the switches need five
 * stable ticks and remember where they changed, and the duty stays inside its bounds.
 * Links control.c only. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include <cmocka.h>

#include "control.h"
#include "hal.h"

static void unwraps_across_the_raw_overflow_and_mirrors(void **state)
{
    (void)state;
    struct control c;
    control_init(&c, INT32_MAX - 5, 1);
    control_measure(&c, INT32_MIN + 4, 0); /* +10 across the wrap */
    assert_true(c.counts == 10);
    control_mirror(&c);
    assert_true(c.counts == -10);
    control_measure(&c, INT32_MIN + 14, 0); /* the raw counter +10: -10 counts now */
    assert_true(c.counts == -20);
}

static void filter_reaches_every_speed_and_zero_exactly(void **state)
{
    (void)state;
    srand(13);
    for (int run = 0; run < 2000; run++) {
        struct control c;
        control_init(&c, 0, (run & 1) ? -1 : 1);
        int32_t raw = 0;
        int32_t v = rand() % 801 - 400; /* counts per tick */
        for (int t = 0; t < 300; t++)
            control_measure(&c, raw += v + (t < 5 ? rand() % 50 : 0), 0);
        assert_int_equal(c.vel_q8, v * 256 * c.sign); /* exactly, no residue */
        for (int t = 0; t < 300; t++)
            control_measure(&c, raw, 0);
        assert_int_equal(c.vel_q8, 0); /* at rest: 0, not 1/256 away from it */
    }
}

static void switches_count_after_five_stable_ticks_from_their_edge(void **state)
{
    (void)state;
    struct control c;
    control_init(&c, 0, 1);
    control_measure(&c, 100, 0);
    control_measure(&c, 200, 1); /* changes here, at 200 counts */
    for (int t = 0; t < 4; t++) {
        assert_int_equal(c.switches, 0);
        control_measure(&c, 300 + t, 1);
    }
    control_measure(&c, 400, 1);
    assert_int_equal(c.switches, 1);
    assert_true(c.sw_edge == 200);
    control_measure(&c, 500, 2); /* a bounce back does not count ... */
    control_measure(&c, 600, 1);
    for (int t = 0; t < 10; t++)
        control_measure(&c, 700, 1);
    assert_int_equal(c.switches, 1); /* ... and switch 1 stays */
}

static void duty_is_bounded_and_current_limited(void **state)
{
    (void)state;
    struct control c;
    const struct control_limits none = {0, 250}, lim = {10, 250}; /* 1 A */
    control_init(&c, 0, 1);
    struct plan far = {(int64_t)100000 * PLANNER_ONE, 0};
    assert_int_equal(control_duty(&c, &far, &none), HAL_DUTY_MAX);
    struct plan back = {-(int64_t)100000 * PLANNER_ONE, 0};
    assert_int_equal(control_duty(&c, &back, &none), -HAL_DUTY_MAX);
    /* With a current limit, the drive stays within 80 % of it around the back-EMF. */
    int16_t d = control_duty(&c, &far, &lim);
    assert_true(d > 0 && d <= 10 * 250 * 8 / 100);
    /* On target, at rest: nothing to do. */
    control_init(&c, 0, 1);
    struct plan here = {0, 0};
    assert_int_equal(control_duty(&c, &here, &none), 0);
    assert_int_equal(c.duty, 0);
    control_release(&c);
    assert_int_equal(c.duty, 0);
}

static void integral_builds_only_at_rest_and_is_bounded(void **state)
{
    (void)state;
    struct control c;
    const struct control_limits none = {0, 250};
    control_init(&c, 0, 1);
    struct plan moving = {3 * PLANNER_ONE, PLANNER_ONE};
    int16_t first = control_duty(&c, &moving, &none);
    assert_int_equal(control_duty(&c, &moving, &none), first); /* nothing summed */
    struct plan rest = {3 * PLANNER_ONE, 0};
    int16_t d0 = control_duty(&c, &rest, &none);
    for (int t = 0; t < 5000; t++)
        control_duty(&c, &rest, &none);
    int16_t d1 = control_duty(&c, &rest, &none);
    assert_true(d1 > d0); /* a standing error pushes harder over time ... */
    assert_true(d1 <= 3 * 8 + 300); /* ... up to 300 per mille over the proportional term */
    control_engage(&c);
    assert_int_equal(control_duty(&c, &rest, &none), d0); /* engaging starts it afresh */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(unwraps_across_the_raw_overflow_and_mirrors),
        cmocka_unit_test(filter_reaches_every_speed_and_zero_exactly),
        cmocka_unit_test(switches_count_after_five_stable_ticks_from_their_edge),
        cmocka_unit_test(duty_is_bounded_and_current_limited),
        cmocka_unit_test(integral_builds_only_at_rest_and_is_bounded),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
