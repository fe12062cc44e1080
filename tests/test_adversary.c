/* test_adversary.c - an adversary's findings where features meet (after issue 25), one
 * named test each, through the bus (tests/bus_host.h) with the plant as ground truth.
 * Each failed before its fix. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "bus_host.h"

/* Duplicate IDs: two feet at ID 1 (a second one added out of the box), one with return
 * delay 0. Each hears the other's answer as an instruction to its own ID; an error answer
 * (ERR 0x20) reads as the unknown instruction 0x20, which the other answered with an
 * error answer, and so on for ever: one PING filled the bus for good, and the storm fed
 * both heartbeats, so two motors turning kept turning after the host had gone. */
static void duplicate_ids_never_answer_each_other_for_ever(void **state)
{
    (void)state;
    vbus_init(&bus);
    bus.step_us = BUS_STEP_US;
    bus.host_baud = 9600;
    (void)vbus_add(&bus, &board_foot, 0);
    bus_run_ms(5);
    assert_int_equal(bus_w8(REG_RETURN_DELAY, 0), 0);
    (void)vbus_add(&bus, &board_foot, 0); /* a new foot out of the box: ID 1 too */
    bus_run_ms(5);
    /* both turn in speed mode, by broadcast (no answers) */
    const uint8_t lim[5] = {REG_CW_LIMIT, 0, 0, 0, 0};
    const uint8_t spd[3] = {REG_MOVING_SPEED, 120, 0};
    (void)bus_ins_to(PROTO_ID_BROADCAST, INS_WRITE, lim, sizeof lim);
    (void)bus_ins_to(PROTO_ID_BROADCAST, INS_WRITE, spd, sizeof spd);
    bus_run_ms(300);
    assert_true(bus.node[0].hal.motor.omega > 1.0 && bus.node[1].hal.motor.omega > 1.0);
    (void)bus_ins(INS_PING, NULL, 0); /* the answers collide or not: the host then goes */
    bus_run_ms(100);
    uint32_t w = bus.wire_len;
    bus_run_ms(1900);
    assert_int_equal(bus.wire_len - w, 0); /* the bus falls quiet */
    for (uint8_t i = 0; i < 2; i++) { /* and the heartbeat stopped both (§7.1) */
        motor_sim_advance(&bus.node[i].hal.motor, bus.now_us);
        assert_true(fabs(bus.node[i].hal.motor.omega) < 0.01);
    }
}

/* Homing in speed mode (an arm with both limits 0 and register 49 = 1): a speed written
 * during homing was answered ERR 0 and turned the arm in speed mode, homing abandoned
 * unannounced: register 24 read 0x11 ("running") for ever, after a speed 0 too, and a
 * host waiting for homing waited for ever. Homing's motion is its own until it ends, as
 * its limits are: the write is refused, and homing finishes. */
static void a_speed_written_during_homing_never_hijacks_it(void **state)
{
    (void)state;
    assert_true(bus_open(&board_arm));
    const uint8_t lim[4] = {0, 0, 0, 0};
    assert_int_equal(bus_write(REG_CW_LIMIT, lim, 4), 0); /* speed mode */
    assert_int_equal(bus_w8(REG_MOVE_WITHOUT_REFERENCE, 1), 0);
    assert_int_equal(bus_w8(REG_HOMING, 1), 0);
    bus_run_ms(100);
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 30), ERR_INSTRUCTION);
    assert_int_equal(bus_home_wait(30000), 2); /* done */
    uint8_t t[REGS_SIZE];
    assert_true(bus_read_table(t));
    assert_int_equal(tab16(t, REG_CW_LIMIT), 0);
    assert_true(tab16(t, REG_CCW_LIMIT) >= 400); /* the switch at 420 degrees */
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 0), 0); /* a stop is never refused */
}

/* A trajectory point whose 16-bit speed is 0x8000 (bit 15, the direction, alone: a
 * magnitude of 0, a stop by §5.4) was accepted, where §4.7 makes speed 0 in a point an
 * instruction error; run, it crawled at the planner's least speed: moving 1 for ever,
 * never reaching the point. */
static void a_trajectory_point_of_speed_0x8000_is_speed_0(void **state)
{
    (void)state;
    assert_true(bus_open(&board_foot));
    const uint8_t path[] = {2, 100, 0, 120, 0, 200, 0, 0x00, 0x80};
    assert_int_equal(bus_ins(INS_TRAJ_WRITE, path, sizeof path), ERR_INSTRUCTION);
    const uint8_t one[] = {1, 100, 0, 0x00, 0x80};
    assert_int_equal(bus_ins(INS_TRAJ_WRITE, one, sizeof one), ERR_INSTRUCTION);
    assert_int_equal(bus_ins(INS_TRAJ_ACTION, NULL, 0), ERR_INSTRUCTION); /* nothing stored */
    uint8_t t[REGS_SIZE];
    bus_run_ms(500);
    assert_true(bus_read_table(t));
    assert_int_equal(t[REG_MOVING], 0);
}

/* Register 13 rescales the limits, rounded: CW 0 / CCW 3 (3 degrees) at resolution 10
 * became 0 / 0 at 255 (25.5 degrees a unit), and the joint silently became a wheel: the
 * next speed written turned it for good. Speed mode comes only from writing 0 to both
 * limits (issue 25), so a joint keeps a CCW limit of at least 1. */
static void a_resolution_change_never_makes_a_joint_a_wheel(void **state)
{
    (void)state;
    assert_true(bus_open(&board_foot));
    const uint8_t lim[4] = {0, 0, 3, 0};
    assert_int_equal(bus_write(REG_CW_LIMIT, lim, 4), 0);
    bus_run_ms(200);
    assert_int_equal(bus_w8(REG_RESOLUTION, 255), 0);
    uint8_t t[REGS_SIZE];
    assert_true(bus_read_table(t));
    assert_int_equal(tab16(t, REG_CW_LIMIT), 0);
    assert_true(tab16(t, REG_CCW_LIMIT) >= 1u);
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 10), 0); /* 255 degrees/s */
    bus_run_ms(1000);
    assert_true(bus_read_table(t));
    struct hal *h = bus_hal();
    motor_sim_advance(&h->motor, bus.now_us);
    assert_true(fabs(h->motor.theta * 57.29577951308232) < 30.0); /* within 0..25.5 */
    assert_int_equal(t[REG_MOVING], 0);
}

/* The base's CUSTOM MOVE writes its ramps into 21/22 lazily: in flash once the servo is
 * idle (issue 25, docs/persistence.md). A host WRITE of 21 with the value such a move had
 * set changed nothing in RAM, so nothing was committed: answered ERR 0, yet a power cut
 * while the base drove lost it (21 read the factory 36). An answered write of an EEPROM
 * register is in flash before its answer, whatever RAM held. */
static void an_answered_write_of_a_lazily_set_ramp_is_in_flash(void **state)
{
    (void)state;
    assert_true(bus_open(&board_base));
    const uint8_t cm[] = {0x01, 0x10, 0x27, 0x2C, 0x01, 20, 20}; /* 10,000 units at 300 */
    assert_int_equal(bus_ins(INS_CUSTOM, cm, sizeof cm), 0);
    bus_run_ms(50);
    assert_int_equal(bus_w8(REG_BASE_ACCELERATION, 20), 0);
    vbus_power_cycle(&bus, 0); /* the base still drives */
    bus_run_ms(20);
    uint8_t t[REGS_SIZE];
    assert_true(bus_read_table(t));
    assert_int_equal(t[REG_BASE_ACCELERATION], 20);
}

/* Read every 20 ms (the heartbeat fed) until moving reads 0 for 200 ms; the table then and
 * the highest position read on the way. */
static void until_rest(uint32_t ms, uint8_t *t, int32_t *hi)
{
    uint32_t still = 0;
    *hi = INT32_MIN;
    for (uint32_t e = 0; e < ms; e += 20u) {
        bus_run_ms(20);
        assert_true(bus_read_table(t));
        int32_t p = tab_position(&board_foot, t);
        *hi = p > *hi ? p : *hi;
        still = t[REG_MOVING] ? 0u : still + 20u;
        if (still >= 200u)
            return;
    }
    fail_msg("still moving after %u ms", ms);
}

/* START/END 1 while a trajectory runs moved the zero under it: the segment running kept
 * its target where it was on the shaft, the points after it were taken in the new frame,
 * so the foot ran a path that was neither the stored one nor that one shifted (A = 300,
 * 50, 250 from 0, START at 150: it went on to 300, then 200 and 400 on the shaft). As a
 * TRAJECTORY WRITE does (docs/decisions.md), it ends the run: the foot stops with its
 * deceleration and holds. */
static void start_end_during_a_trajectory_ends_it(void **state)
{
    (void)state;
    uint8_t t[REGS_SIZE];
    int32_t hi;
    assert_true(bus_open(&board_foot));
    const uint8_t a[] = {3, 44, 1, 120, 0, 50, 0, 120, 0, 250, 0, 120, 0};
    assert_int_equal(bus_ins(INS_TRAJ_WRITE, a, sizeof a), 0);
    assert_int_equal(bus_ins(INS_TRAJ_ACTION, NULL, 0), 0);
    for (int i = 0; i < 400; i++) {
        bus_run_ms(5);
        assert_true(bus_read_table(t));
        if (tab_position(&board_foot, t) >= 150)
            break;
    }
    const uint8_t one = 1;
    assert_int_equal(bus_ins(INS_START_END, &one, 1), 0);
    until_rest(10000, t, &hi);
    int32_t p = tab_position(&board_foot, t);
    assert_true(p >= 0 && p < 60 && hi < 60); /* stopped within its braking distance */
    assert_int_equal(tab16(t, REG_GOAL_POSITION), p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(duplicate_ids_never_answer_each_other_for_ever),
        cmocka_unit_test(a_speed_written_during_homing_never_hijacks_it),
        cmocka_unit_test(a_trajectory_point_of_speed_0x8000_is_speed_0),
        cmocka_unit_test(a_resolution_change_never_makes_a_joint_a_wheel),
        cmocka_unit_test(an_answered_write_of_a_lazily_set_ramp_is_in_flash),
        cmocka_unit_test(start_end_during_a_trajectory_ends_it),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
