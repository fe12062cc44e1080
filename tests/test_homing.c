/* test_homing.c - the §9 homing sequence (src/homing.c) on its own: a shaft that turns
 * one step per tick in the direction homing asks for, with switch 1 at and below 0 and
 * switch 2 at and above the end, from every start and travel. Nothing else is linked. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "homing.h"

#define STEP 3
#define MAX_TRAVEL 5000

static uint8_t switches_at(int64_t pos, int64_t end)
{
    return (uint8_t)((pos <= 0 ? 1u : 0u) | (pos >= end ? 2u : 0u));
}

/* Run homing on the model shaft; returns the event that ended it and where. */
static uint8_t run(int64_t start, int64_t end, int64_t *zero_at, int64_t *end_at, int *ticks)
{
    struct homing h;
    int64_t pos = start;
    homing_start(&h, switches_at(pos, end), pos, MAX_TRAVEL);
    *zero_at = *end_at = INT64_MIN;
    for (*ticks = 0; *ticks < 100000; (*ticks)++) {
        uint8_t ev = homing_step(&h, switches_at(pos, end), pos);
        if (ev == HOMING_EVENT_FAIL)
            return ev;
        if (ev == HOMING_EVENT_ZERO) {
            assert_int_equal(*zero_at, INT64_MIN); /* the zero is found once */
            *zero_at = pos;
        }
        if (ev == HOMING_EVENT_END) {
            *end_at = pos;
            assert_true(homing_returning(&h));
            /* From now on homing only returns onto the end. */
            assert_int_equal(homing_step(&h, switches_at(pos, end), pos), HOMING_EVENT_RETURN);
            return ev;
        }
        assert_false(homing_returning(&h));
        pos += homing_dir(&h) * STEP;
    }
    fail_msg("homing never ended");
    return HOMING_EVENT_FAIL;
}

static void finds_zero_then_end_from_anywhere(void **state)
{
    (void)state;
    for (int64_t end = 300; end <= 3000; end += 450) {
        for (int64_t start = -20; start <= end + 20; start += 17) {
            int64_t zero_at, end_at;
            int ticks;
            uint8_t ev = run(start, end, &zero_at, &end_at, &ticks);
            assert_int_equal(ev, HOMING_EVENT_END);
            /* The zero is seen on switch 1 within one step of its edge, the end on
             * switch 2 within one step of its edge, in that order. */
            assert_true(zero_at <= 0 && zero_at > -STEP - 1);
            assert_true(end_at >= end && end_at < end + STEP + 1);
        }
    }
}

static void starting_on_switch_one_backs_off_first(void **state)
{
    (void)state;
    struct homing h;
    homing_start(&h, 1u, -5, MAX_TRAVEL);
    assert_int_equal(homing_dir(&h), 1); /* off the switch, toward the end */
    assert_int_equal(homing_step(&h, 1u, -2), HOMING_EVENT_RUN);
    assert_int_equal(homing_dir(&h), 1);
    assert_int_equal(homing_step(&h, 0u, 1), HOMING_EVENT_RUN); /* off it: now seek it */
    assert_int_equal(homing_dir(&h), -1);
    assert_int_equal(homing_step(&h, 1u, 0), HOMING_EVENT_ZERO);
    assert_int_equal(homing_dir(&h), 1);
}

static void both_switches_fail_in_every_phase(void **state)
{
    (void)state;
    struct homing h;
    homing_start(&h, 1u, 0, MAX_TRAVEL); /* backing off */
    assert_int_equal(homing_step(&h, 3u, 0), HOMING_EVENT_FAIL);
    homing_start(&h, 0u, 10, MAX_TRAVEL); /* seeking */
    assert_int_equal(homing_step(&h, 3u, 9), HOMING_EVENT_FAIL);
    homing_start(&h, 0u, 10, MAX_TRAVEL);
    assert_int_equal(homing_step(&h, 1u, 0), HOMING_EVENT_ZERO); /* now toward the end */
    assert_int_equal(homing_step(&h, 3u, 5), HOMING_EVENT_FAIL);
}

static void a_switch_not_found_within_the_travel_fails(void **state)
{
    (void)state;
    int64_t zero_at, end_at;
    int ticks;
    /* The end is farther than a phase may run: found zero, then gave up. */
    assert_int_equal(run(100, MAX_TRAVEL + 200, &zero_at, &end_at, &ticks), HOMING_EVENT_FAIL);
    assert_true(zero_at != INT64_MIN);
    assert_true(ticks * STEP <= 100 + MAX_TRAVEL + 4 * STEP); /* gave up promptly */
    /* Switch 1 farther than the travel: fails while seeking, never zeroed. */
    assert_int_equal(run(MAX_TRAVEL + 100, 2 * MAX_TRAVEL, &zero_at, &end_at, &ticks),
                     HOMING_EVENT_FAIL);
    assert_true(zero_at == INT64_MIN);
    /* The travel counts per phase: just within it in each phase succeeds. */
    assert_int_equal(run(MAX_TRAVEL - 2 * STEP, MAX_TRAVEL - 2 * STEP, &zero_at, &end_at,
                         &ticks),
                     HOMING_EVENT_END);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(finds_zero_then_end_from_anywhere),
        cmocka_unit_test(starting_on_switch_one_backs_off_first),
        cmocka_unit_test(both_switches_fail_in_every_phase),
        cmocka_unit_test(a_switch_not_found_within_the_travel_fails),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
