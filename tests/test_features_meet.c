/* test_features_meet.c - issue 25's findings where two features meet, one named test each,
 * through the bus (tests/bus_host.h) with the plant as ground truth. Each failed on the
 * code before the fix; tests/test_invariants.c checks the rules they break in general. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "bus_host.h"

#define RAD_TO_DEG 57.29577951308232

static double shaft_deg(void)
{
    struct hal *h = bus_hal();
    motor_sim_advance(&h->motor, bus.now_us);
    return h->motor.theta * RAD_TO_DEG;
}

static void table(uint8_t *t)
{
    if (!bus_read_table(t))
        fail_msg("no answer to READ 0..49");
}

/* Read every 20 ms (the heartbeat fed) until moving reads 0 and stays 0 for 200 ms, for
 * at most ms; the table then, and the lowest and highest position read on the way. */
static void until_rest(uint32_t ms, uint8_t *t, int32_t *lo, int32_t *hi)
{
    uint32_t still = 0;
    *lo = INT32_MAX;
    *hi = INT32_MIN;
    for (uint32_t e = 0; e < ms; e += 20u) {
        bus_run_ms(20);
        table(t);
        int32_t p = tab_position(&board_foot, t);
        *lo = p < *lo ? p : *lo;
        *hi = p > *hi ? p : *hi;
        still = t[REG_MOVING] ? 0u : still + 20u;
        if (still >= 200u)
            return;
    }
    fail_msg("still moving after %u ms (position %d)", ms, tab_position(&board_foot, t));
}

/* Read until the position passes `at` in the direction of travel. */
static void until_past(int32_t at, bool up)
{
    uint8_t t[REGS_SIZE];
    for (int i = 0; i < 400; i++) {
        bus_run_ms(5);
        table(t);
        int32_t p = tab_position(&board_foot, t);
        if (up ? p >= at : p <= at)
            return;
    }
    fail_msg("the foot never passed %d", at);
}

static void foot(void)
{
    assert_true(bus_open(&board_foot));
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 120), 0);
}

static int w_limits(uint16_t cw, uint16_t ccw)
{
    const uint8_t d[4] = {(uint8_t)cw, (uint8_t)(cw >> 8), (uint8_t)ccw, (uint8_t)(ccw >> 8)};
    return bus_write(REG_CW_LIMIT, d, 4);
}

/* The first example: a foot moving to 300; CCW limit 200 written at about 90. It
 * rested at 300, the goal reading 300 with CCW 200. */
static void a_limit_narrowed_mid_move_holds(void **state)
{
    (void)state;
    uint8_t t[REGS_SIZE];
    int32_t lo, hi;
    foot();
    assert_int_equal(bus_w16(REG_GOAL_POSITION, 300), 0);
    until_past(90, true);
    assert_int_equal(bus_w16(REG_CCW_LIMIT, 200), 0);
    table(t);
    assert_int_equal(tab16(t, REG_GOAL_POSITION), 200); /* clamped at once (§5.4) */
    until_rest(6000, t, &lo, &hi);
    assert_int_equal(tab_position(&board_foot, t), 200);
    assert_true(hi <= 200);
    assert_true(fabs(shaft_deg() - 200.0) < 0.5);
    /* START/END 2 mid-move: the end is where the shaft is, and the move ends there */
    assert_int_equal(bus_w16(REG_CCW_LIMIT, 360), 0);
    assert_int_equal(bus_w16(REG_GOAL_POSITION, 350), 0);
    until_past(250, true);
    const uint8_t end = 2;
    assert_int_equal(bus_ins(INS_START_END, &end, 1), 0);
    until_rest(6000, t, &lo, &hi);
    uint16_t ccw = tab16(t, REG_CCW_LIMIT);
    assert_true(ccw >= 250 && ccw < 300);
    assert_int_equal(tab_position(&board_foot, t), ccw); /* braked past it, came back */
    assert_int_equal(tab16(t, REG_GOAL_POSITION), ccw);
}

/* A shaft already past a new limit brakes with its deceleration and comes back. */
static void a_limit_behind_the_shaft_brings_it_back(void **state)
{
    (void)state;
    uint8_t t[REGS_SIZE];
    int32_t lo, hi;
    foot();
    assert_int_equal(bus_w8(REG_DECELERATION, 10), 0); /* 100 deg/s^2: 72 deg to stop */
    assert_int_equal(bus_w16(REG_GOAL_POSITION, 340), 0);
    until_past(150, true);
    assert_int_equal(bus_w16(REG_CCW_LIMIT, 100), 0);
    until_rest(8000, t, &lo, &hi);
    assert_true(hi > 170); /* it braked on, past 150 */
    assert_int_equal(tab_position(&board_foot, t), 100);
}

/* Limits written while a trajectory runs, and before a stored one starts: its points are
 * clamped to them. */
static void a_trajectory_keeps_within_new_limits(void **state)
{
    (void)state;
    uint8_t t[REGS_SIZE];
    int32_t lo, hi;
    foot();
    const uint8_t path[] = {3, 44, 1, 120, 0, 50, 0, 120, 0, 250, 0, 120, 0}; /* 300 50 250 */
    assert_int_equal(bus_ins(INS_TRAJ_WRITE, path, sizeof path), 0);
    assert_int_equal(bus_ins(INS_TRAJ_ACTION, NULL, 0), 0);
    until_past(100, true);
    assert_int_equal(w_limits(80, 200), 0);
    until_rest(10000, t, &lo, &hi);
    assert_true(hi <= 200);
    assert_int_equal(tab_position(&board_foot, t), 200); /* 250 clamped */
    assert_int_equal(w_limits(150, 360), 0); /* then narrowed before a start */
    until_rest(3000, t, &lo, &hi);
    assert_int_equal(bus_ins(INS_TRAJ_ACTION, NULL, 0), 0);
    until_rest(10000, t, &lo, &hi);
    assert_true(lo >= 150);
    assert_int_equal(tab_position(&board_foot, t), 200); /* the old 200 */
}

/* The second example: a foot turning at 120 deg/s in speed mode; CW 0 / CCW 200
 * written (answered ERR 0): it kept turning, 547, 583, ... with moving 1. */
static void leaving_speed_mode_stops_within_the_limits(void **state)
{
    (void)state;
    uint8_t t[REGS_SIZE];
    int32_t lo, hi;
    foot();
    assert_int_equal(w_limits(0, 0), 0);
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 120), 0); /* turning */
    until_past(150, true);
    assert_int_equal(w_limits(0, 200), 0);
    until_rest(6000, t, &lo, &hi);
    int32_t p = tab_position(&board_foot, t);
    assert_true(p >= 0 && p <= 200 && hi <= 200);
    assert_int_equal(tab16(t, REG_GOAL_POSITION), p);
    bus_run_ms(1000);
    table(t);
    assert_int_equal(tab_position(&board_foot, t), p); /* holds */
}

/* The third example: A = 300, 50, 250 running; B = 200, 20, 330, 10 written: the
 * foot went 300 -> 330 -> 10, a path neither A nor B, with no ACTION. A TRAJECTORY WRITE
 * during a run stops it (docs/decisions.md); B runs at the next ACTION. */
static void a_trajectory_write_never_splices_the_running_one(void **state)
{
    (void)state;
    uint8_t t[REGS_SIZE];
    int32_t lo, hi;
    foot();
    const uint8_t a[] = {3, 44, 1, 120, 0, 50, 0, 120, 0, 250, 0, 120, 0};
    const uint8_t b[] = {4, 200, 0, 120, 0, 20, 0, 120, 0, 74, 1, 120, 0, 10, 0, 120, 0};
    assert_int_equal(bus_ins(INS_TRAJ_WRITE, a, sizeof a), 0);
    assert_int_equal(bus_ins(INS_TRAJ_ACTION, NULL, 0), 0);
    until_past(200, true);
    assert_int_equal(bus_ins(INS_TRAJ_WRITE, b, sizeof b), 0);
    until_rest(6000, t, &lo, &hi);
    int32_t p = tab_position(&board_foot, t);
    assert_true(p >= 200 && p < 300 && hi < 300); /* stopped on A's way to 300 */
    assert_int_equal(tab16(t, REG_GOAL_POSITION), p);
    bus_run_ms(1000);
    table(t);
    assert_int_equal(tab_position(&board_foot, t), p);
    assert_int_equal(bus_ins(INS_TRAJ_ACTION, NULL, 0), 0); /* now B, whole */
    until_rest(15000, t, &lo, &hi);
    assert_int_equal(tab_position(&board_foot, t), 10);
    assert_true(hi >= 329 && lo <= 20);
}

/* The fourth: START/END 1, then END with the shaft still there set both limits to
 * 0, speed mode, answered ERR 0. Speed mode comes only from writing 0 to both limits.
 * And START/END 1 during a move left the goal reading the old goal with moving 0. */
static void start_end_keeps_a_joint_a_joint_and_the_goal_true(void **state)
{
    (void)state;
    uint8_t t[REGS_SIZE];
    int32_t lo, hi;
    foot();
    const uint8_t one = 1, two = 2;
    assert_int_equal(bus_ins(INS_START_END, &one, 1), 0);
    assert_int_equal(bus_ins(INS_START_END, &two, 1), ERR_INSTRUCTION);
    table(t);
    assert_int_equal(tab16(t, REG_CW_LIMIT), 0);
    assert_int_equal(tab16(t, REG_CCW_LIMIT), 360);
    assert_int_equal(bus_w16(REG_GOAL_POSITION, 200), 0);
    until_past(100, true);
    assert_int_equal(bus_ins(INS_START_END, &one, 1), 0); /* zero here, mid-move */
    until_rest(6000, t, &lo, &hi);
    assert_int_equal(tab16(t, REG_GOAL_POSITION), tab_position(&board_foot, t));
}

/* The base chassis: CUSTOM MOVE alternating two ramp profiles spent the 64-commit
 * burst in about 7 s, and every configuration write after that was answered but deferred
 * for up to 64 s (lost at a power cut). The ramps now reach the flash lazily: a hundred
 * such moves spend no token, and the configuration write after them is in flash at once. */
static void custom_move_ramps_on_the_base_spend_no_budget(void **state)
{
    (void)state;
    assert_true(bus_open(&board_base));
    const struct store *st = &bus.node[0].servo.store;
    uint8_t tokens = store_tokens(st); /* bus_open's own writes spent some */
    for (int i = 0; i < 100; i++) {
        uint8_t ramp = (uint8_t)(i % 2 ? 20 : 60); /* two profiles, a move each 70 ms */
        const uint8_t cm[] = {0x01, 0x64, 0x00, 0x2C, 0x01, ramp, ramp};
        assert_int_equal(bus_ins(INS_CUSTOM, cm, sizeof cm), 0);
        bus_run_ms(70);
    }
    assert_int_equal(store_tokens(st), tokens);
    assert_int_equal(bus_w8(REG_TEMPERATURE_LIMIT, 70), 0);
    /* A token spent is a commit that ran: in flash before its answer (persistence.md). */
    assert_int_equal(store_tokens(st), tokens - 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(a_limit_narrowed_mid_move_holds),
        cmocka_unit_test(a_limit_behind_the_shaft_brings_it_back),
        cmocka_unit_test(a_trajectory_keeps_within_new_limits),
        cmocka_unit_test(leaving_speed_mode_stops_within_the_limits),
        cmocka_unit_test(a_trajectory_write_never_splices_the_running_one),
        cmocka_unit_test(start_end_keeps_a_joint_a_joint_and_the_goal_true),
        cmocka_unit_test(custom_move_ramps_on_the_base_spend_no_budget),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
