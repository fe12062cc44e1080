/* test_command.c - what host commands mean to the motor side (src/command.c), with the
 * modes it starts (motion_mode.h) and the safety layer faked: every register write and
 * motion instruction starts the one mode §4-§6 give it, refuses what may not run, and
 * never refuses a stop (rule 3). Links command.c and the register table only. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "command.h"
#include "motion.h"
#include "motion_mode.h"
#include "proto.h"
#include "safety.h"
#include "servo.h"

/* ---- fakes: the modes record what they were asked, safety says what the test wants */

static char calls[256];
static struct {
    bool may_start, referenced, unloaded;
    int32_t present;
} fake;

static void called(const char *what)
{
    strncat(calls, what, sizeof calls - strlen(calls) - 1);
    strncat(calls, ";", sizeof calls - strlen(calls) - 1);
}

struct scale motion_scale(const struct servo *s)
{
    return (struct scale){s->board->counts_per_rev, s->regs.mem[REG_RESOLUTION]};
}
int32_t motion_present_units(const struct servo *s)
{
    (void)s;
    return fake.present;
}
void motion_set_limits(struct servo *s, uint16_t speed)
{
    (void)s;
    char b[32];
    snprintf(b, sizeof b, "limits %u", speed);
    called(b);
}
bool motion_may_start(const struct servo *s)
{
    (void)s;
    return fake.may_start;
}
bool motion_referenced_for(const struct servo *s, bool speed_mode)
{
    (void)s;
    (void)speed_mode;
    return fake.referenced;
}
void motion_engage(struct servo *s)
{
    (void)s;
    called("engage");
}
void motion_coast(struct servo *s)
{
    s->motion.mode = MOTION_OFF;
    called("coast");
}
void motion_hold_here(struct servo *s)
{
    s->motion.mode = MOTION_HOLD;
    called("hold");
}
void motion_brake_hold(struct servo *s)
{
    (void)s;
    called("brake");
}
void motion_start_homing(struct servo *s)
{
    s->motion.mode = MOTION_HOME;
    called("home");
}
void motion_start_move(struct servo *s, int32_t units, uint16_t speed)
{
    s->motion.mode = MOTION_MOVE;
    char b[40];
    snprintf(b, sizeof b, "move %d %u", (int)units, speed);
    called(b);
}
void motion_start_speed(struct servo *s, uint16_t speed)
{
    s->motion.mode = MOTION_SPEED;
    char b[32];
    snprintf(b, sizeof b, "speed %u", speed);
    called(b);
}
void motion_start_traj(struct servo *s)
{
    (void)s;
    called("traj");
}
void motion_rest_span(const struct servo *s, int32_t *lo, int32_t *hi)
{
    (void)s;
    *lo = *hi = fake.present;
}
uint8_t motion_mode(const struct servo *s)
{
    return s->motion.mode;
}
void motion_stop_soft(struct servo *s)
{
    s->motion.mode = MOTION_STOP;
    called("stop");
}
void motion_mirror(struct servo *s, int8_t sign)
{
    (void)s;
    char b[32];
    snprintf(b, sizeof b, "mirror %d", sign);
    called(b);
}
void motion_homing_abort(struct servo *s)
{
    if (s->motion.mode == MOTION_HOME)
        motion_hold_here(s);
}
void motion_new_ramps(struct servo *s)
{
    (void)s;
    called("ramps");
}
void motion_zero_here(struct servo *s)
{
    s->motion.zero = s->motion.ctl.counts;
    called("zero");
}
void motion_forget_reference(struct servo *s)
{
    (void)s;
    called("forget");
}
void motion_limits_changed(struct servo *s)
{
    (void)s;
    called("limits changed");
}
bool safety_unloaded(const struct safety *sf)
{
    (void)sf;
    return fake.unloaded;
}

/* ---- harness ------------------------------------------------------------------------ */

static struct servo s;

static void fresh(const struct board *b)
{
    memset(&s, 0, sizeof s);
    s.board = b;
    regs_init(&s.regs, b);
    calls[0] = 0;
    fake.may_start = fake.referenced = true;
    fake.unloaded = false;
    fake.present = 0;
}

/* A host write as write.c does it: checked, then the values, then command_written. */
static bool write16(uint8_t addr, uint16_t v)
{
    uint8_t d[2] = {(uint8_t)v, (uint8_t)(v >> 8)};
    const struct reg_write w = {addr, regs_table[addr].size, s.regs.mem[REG_RESOLUTION], d,
                               regs_mask(addr, regs_table[addr].size)};
    if (command_write_check(&s, &w))
        return false;
    regs_set(&s.regs, addr, v);
    calls[0] = 0;
    command_written(&s, &w);
    return true;
}

/* ---- tests -------------------------------------------------------------------------- */

static void a_stop_is_never_refused_and_drops_the_torque(void **state)
{
    (void)state;
    fresh(&board_base); /* speed mode */
    fake.unloaded = true;
    fake.referenced = false;
    assert_true(write16(REG_MOVING_SPEED, 0x8000)); /* 0 with the direction bit */
    assert_string_equal(calls, "coast;");
    assert_true(write16(REG_MOVING_SPEED, 0));
    assert_string_equal(calls, "coast;");
    struct custom_move cm = {.speed = 0x8000};
    calls[0] = 0;
    command_custom_move(&s, &cm);
    assert_string_equal(calls, "coast;");
    assert_false(write16(REG_MOVING_SPEED, 5)); /* anything else is refused unloaded */
}

static void a_goal_moves_absolute_or_on_the_base_relative(void **state)
{
    (void)state;
    fresh(&board_arm);
    regs_set(&s.regs, REG_MOVING_SPEED, 300);
    assert_true(write16(REG_GOAL_POSITION, 1200));
    assert_string_equal(calls, "move 1200 300;");
    fresh(&board_base);
    regs_set(&s.regs, REG_MOVING_SPEED, 300);
    fake.present = 1000;
    assert_true(write16(REG_GOAL_POSITION, (uint16_t)-250));
    assert_string_equal(calls, "move 750 300;");
}

static void a_goal_is_refused_unloaded_or_unreferenced(void **state)
{
    (void)state;
    fresh(&board_arm);
    fake.referenced = false;
    assert_false(write16(REG_GOAL_POSITION, 100));
    fake.referenced = true;
    fake.unloaded = true;
    assert_false(write16(REG_GOAL_POSITION, 100));
    assert_string_equal(calls, "");
}

static void speed_turns_in_speed_mode_and_sets_the_cruise_in_a_move(void **state)
{
    (void)state;
    fresh(&board_base);
    assert_true(write16(REG_MOVING_SPEED, 0x8000 | 90));
    assert_string_equal(calls, "speed 32858;");
    fresh(&board_arm); /* position mode */
    assert_true(write16(REG_MOVING_SPEED, 90));
    assert_string_equal(calls, ""); /* starts nothing */
    s.motion.mode = MOTION_MOVE;
    assert_true(write16(REG_MOVING_SPEED, 120));
    assert_string_equal(calls, "limits 120;"); /* re-planned from here */
}

static void homing_brake_sleep_and_resolution(void **state)
{
    (void)state;
    fresh(&board_arm);
    assert_true(write16(REG_HOMING, 1));
    assert_string_equal(calls, "home;");
    assert_true(write16(REG_HOMING, 0)); /* 0 aborts a running homing */
    assert_string_equal(calls, "hold;");
    assert_true(write16(REG_HOMING, 0)); /* and does nothing otherwise */
    assert_string_equal(calls, "");
    assert_true(write16(REG_BRAKE, 1));
    assert_string_equal(calls, "brake;");
    assert_true(write16(REG_SLEEP, 1));
    assert_string_equal(calls, "coast;");
    s.motion.mode = MOTION_MOVE;
    assert_true(write16(REG_RESOLUTION, 2));
    /* §5: a resolution change stops any motion, and the rescaled limits apply */
    assert_string_equal(calls, "hold;limits changed;");
    assert_int_equal(regs_get(&s.regs, REG_CCW_LIMIT), 1800); /* 360 deg in 0.2 deg */
    fake.unloaded = true;
    assert_false(write16(REG_HOMING, 1));
}

static void the_zero_side_mirrors_the_motor(void **state)
{
    (void)state;
    fresh(&board_arm);
    assert_true(write16(REG_HOMING_ZERO_SIDE, 2));
    assert_string_equal(calls, "mirror -1;");
    assert_true(write16(REG_HOMING_ZERO_SIDE, 1));
    assert_string_equal(calls, "mirror 1;");
}

static void new_limits_reach_what_runs(void **state)
{
    (void)state;
    fresh(&board_foot);
    assert_true(write16(REG_CCW_LIMIT, 200));
    assert_string_equal(calls, "limits changed;");
    assert_true(write16(REG_CW_LIMIT, 20));
    assert_string_equal(calls, "limits changed;");
    fake.unloaded = true; /* even unloaded: the limits are settings, not motion */
    assert_true(write16(REG_CW_LIMIT, 30));
    assert_string_equal(calls, "limits changed;");
    s.motion.mode = MOTION_HOME; /* homing measures them */
    assert_false(write16(REG_CW_LIMIT, 40));
}

static void a_trajectory_written_while_one_runs_stops_it(void **state)
{
    (void)state;
    fresh(&board_foot);
    command_traj_written(&s);
    assert_string_equal(calls, ""); /* nothing runs: stored only */
    s.motion.mode = MOTION_TRAJ;
    command_traj_written(&s);
    assert_string_equal(calls, "stop;"); /* ramped down, never spliced */
}

static void custom_move_moves_only_when_it_may_start(void **state)
{
    (void)state;
    fresh(&board_arm);
    struct custom_move cm = {.absolute = 1, .target = 900, .speed = 50}; /* past CCW 360 */
    fake.may_start = false;
    assert_false(command_may_move(&s));
    fake.may_start = true;
    fake.referenced = false;
    assert_false(command_may_move(&s));
    fake.referenced = true;
    assert_true(command_may_move(&s));
    command_custom_move(&s, &cm);
    assert_string_equal(calls, "move 360 50;"); /* clamped to the CCW limit */
    /* relative, backwards, clamped to the CW limit */
    calls[0] = 0;
    fake.present = 100;
    struct custom_move back = {.absolute = 0, .target = 300, .speed = 0x8000 | 50};
    command_custom_move(&s, &back);
    assert_string_equal(calls, "move 0 50;");
}

static void start_end_sets_the_zero_and_the_end(void **state)
{
    (void)state;
    fresh(&board_foot);
    s.motion.ctl.counts = 4321;
    assert_int_equal(command_start_end(&s, 1), 0);
    assert_string_equal(calls, "zero;limits changed;");
    assert_true(s.motion.zero == 4321);
    assert_int_equal(regs_get(&s.regs, REG_CW_LIMIT), 0);
    fake.present = 700;
    assert_int_equal(command_start_end(&s, 2), 0);
    assert_int_equal(regs_get(&s.regs, REG_CCW_LIMIT), 700);
    regs_set(&s.regs, REG_CW_LIMIT, 100);
    fake.present = 50; /* below the CW limit: refused, nothing changes */
    assert_int_equal(command_start_end(&s, 2), ERR_INSTRUCTION);
    assert_int_equal(regs_get(&s.regs, REG_CCW_LIMIT), 700);
}

/* Issue 25: END with the shaft still at the start point (START/END 1, then a move that
 * was refused or stopped) set both limits to 0 and made the joint a wheel, answered ERR 0.
 * Speed mode is entered only by writing 0 to both limits. */
static void end_at_the_start_point_is_refused(void **state)
{
    (void)state;
    fresh(&board_foot);
    assert_int_equal(command_start_end(&s, 1), 0);
    fake.present = 0;
    calls[0] = 0;
    assert_int_equal(command_start_end(&s, 2), ERR_INSTRUCTION);
    assert_string_equal(calls, "");
    assert_int_equal(regs_get(&s.regs, REG_CW_LIMIT), 0);
    assert_int_equal(regs_get(&s.regs, REG_CCW_LIMIT), 360); /* position mode still */
}

/* §5: changing register 13 rescales the limits and the goal to the same angles (rounded),
 * drops the stored trajectory, and stops and holds. */
static void resolution_change_rescales_and_clears_trajectory(void **state)
{
    (void)state;
    fresh(&board_foot);
    regs_set(&s.regs, REG_CW_LIMIT, 90);
    regs_set(&s.regs, REG_GOAL_POSITION, 180);
    s.traj.count = 1;
    s.motion.mode = MOTION_HOLD; /* at rest: the goal keeps meaning the same angle */
    assert_true(write16(REG_RESOLUTION, 1)); /* 1 degree -> 0.1 degree per unit */
    assert_string_equal(calls, "limits changed;");
    assert_int_equal(regs_get(&s.regs, REG_CW_LIMIT), 900);
    assert_int_equal(regs_get(&s.regs, REG_CCW_LIMIT), 3600);
    assert_int_equal(regs_get(&s.regs, REG_GOAL_POSITION), 1800);
    assert_int_equal(s.traj.count, 0);
    assert_true(write16(REG_RESOLUTION, 3));
    assert_int_equal(regs_get(&s.regs, REG_CW_LIMIT), 300);
    assert_int_equal(regs_get(&s.regs, REG_CCW_LIMIT), 1200);
    assert_int_equal(regs_get(&s.regs, REG_GOAL_POSITION), 600);
    assert_true(write16(REG_RESOLUTION, 7)); /* rounded: 128.6, 514.3, 257.1 */
    assert_int_equal(regs_get(&s.regs, REG_CW_LIMIT), 129);
    assert_int_equal(regs_get(&s.regs, REG_CCW_LIMIT), 514);
    assert_int_equal(regs_get(&s.regs, REG_GOAL_POSITION), 257);
    s.motion.mode = MOTION_MOVE;
    assert_true(write16(REG_RESOLUTION, 7)); /* the same value changes nothing (§5) */
    assert_string_equal(calls, "");
    assert_int_equal(regs_get(&s.regs, REG_CW_LIMIT), 129);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(a_stop_is_never_refused_and_drops_the_torque),
        cmocka_unit_test(a_goal_moves_absolute_or_on_the_base_relative),
        cmocka_unit_test(a_goal_is_refused_unloaded_or_unreferenced),
        cmocka_unit_test(speed_turns_in_speed_mode_and_sets_the_cruise_in_a_move),
        cmocka_unit_test(homing_brake_sleep_and_resolution),
        cmocka_unit_test(the_zero_side_mirrors_the_motor),
        cmocka_unit_test(new_limits_reach_what_runs),
        cmocka_unit_test(a_trajectory_written_while_one_runs_stops_it),
        cmocka_unit_test(custom_move_moves_only_when_it_may_start),
        cmocka_unit_test(start_end_sets_the_zero_and_the_end),
        cmocka_unit_test(end_at_the_start_point_is_refused),
        cmocka_unit_test(resolution_change_rescales_and_clears_trajectory),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
