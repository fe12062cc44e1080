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

#include "motion.h"
#include "motion_mode.h"
#include "proto.h"
#include "safety.h"
#include "servo.h"

/* ---- fakes: the modes record what they were asked, safety says what the test wants */

static char calls[256];
static struct {
    bool may_start, referenced, unloaded, may_clear;
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
    (void)s;
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
bool safety_unloaded(const struct safety *sf)
{
    (void)sf;
    return fake.unloaded;
}
bool safety_may_clear(const struct safety *sf)
{
    (void)sf;
    return fake.may_clear;
}
void safety_clear(struct safety *sf)
{
    (void)sf;
    called("clear");
}

/* ---- harness ------------------------------------------------------------------------ */

static struct servo s;

static void fresh(const struct board *b)
{
    memset(&s, 0, sizeof s);
    s.board = b;
    regs_init(&s.regs, b);
    calls[0] = 0;
    fake.may_start = fake.referenced = fake.may_clear = true;
    fake.unloaded = false;
    fake.present = 0;
}

/* A host write as dispatch does it: allowed?, then the values, then motion_on_write. */
static bool write16(uint8_t addr, uint16_t v)
{
    uint8_t d[2] = {(uint8_t)v, (uint8_t)(v >> 8)};
    uint8_t n = regs_table[addr].size;
    if (!motion_write_allowed(&s, addr, d, n))
        return false;
    regs_set(&s.regs, addr, v);
    calls[0] = 0;
    motion_on_write(&s, addr, n);
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
    assert_int_equal(motion_custom_allowed(&s, &cm), 0);
    calls[0] = 0;
    motion_custom_move(&s, &cm);
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
    assert_true(write16(REG_BRAKE, 1));
    assert_string_equal(calls, "brake;");
    assert_true(write16(REG_SLEEP, 1));
    assert_string_equal(calls, "coast;");
    assert_true(write16(REG_RESOLUTION, 2));
    assert_string_equal(calls, "hold;"); /* §5: a resolution change stops any motion */
    fake.unloaded = true;
    assert_false(write16(REG_HOMING, 1));
}

static void mirroring_the_motor_forgets_the_reference(void **state)
{
    (void)state;
    fresh(&board_arm);
    s.motion.ctl.sign = 1;
    s.motion.ctl.counts = 500;
    s.motion.zero = 100;
    s.motion.referenced = 1;
    assert_true(write16(REG_HOMING_ZERO_SIDE, 2));
    assert_string_equal(calls, "coast;");
    assert_int_equal(s.motion.ctl.sign, -1);
    assert_true(s.motion.ctl.counts == -500 && s.motion.zero == -100);
    assert_int_equal(s.motion.referenced, 0);
}

static void clearing_an_unload_only_once_its_cause_is_gone(void **state)
{
    (void)state;
    fresh(&board_arm);
    fake.unloaded = true;
    fake.may_clear = false;
    assert_false(write16(REG_CLEAR_UNLOAD, 1));
    fake.may_clear = true;
    assert_true(write16(REG_CLEAR_UNLOAD, 1));
    assert_string_equal(calls, "clear;"); /* and nothing moves */
}

static void custom_move_refused_when_it_may_not_start(void **state)
{
    (void)state;
    fresh(&board_arm);
    struct custom_move cm = {.absolute = 1, .target = 900, .speed = 50}; /* past CCW 360 */
    fake.may_start = false;
    assert_int_equal(motion_custom_allowed(&s, &cm), ERR_INSTRUCTION);
    fake.may_start = true;
    fake.referenced = false;
    assert_int_equal(motion_custom_allowed(&s, &cm), ERR_INSTRUCTION);
    fake.referenced = true;
    assert_int_equal(motion_custom_allowed(&s, &cm), 0);
    motion_custom_move(&s, &cm);
    assert_string_equal(calls, "move 360 50;"); /* clamped to the CCW limit */
    /* relative, backwards, clamped to the CW limit */
    calls[0] = 0;
    fake.present = 100;
    struct custom_move back = {.absolute = 0, .target = 300, .speed = 0x8000 | 50};
    motion_custom_move(&s, &back);
    assert_string_equal(calls, "move 0 50;");
}

static void start_end_sets_the_zero_and_the_end(void **state)
{
    (void)state;
    fresh(&board_foot);
    s.motion.ctl.counts = 4321;
    assert_int_equal(motion_start_end(&s, 1), 0);
    assert_true(s.motion.zero == 4321);
    assert_int_equal(regs_get(&s.regs, REG_CW_LIMIT), 0);
    fake.present = 700;
    assert_int_equal(motion_start_end(&s, 2), 0);
    assert_int_equal(regs_get(&s.regs, REG_CCW_LIMIT), 700);
    regs_set(&s.regs, REG_CW_LIMIT, 100);
    fake.present = 50; /* below the CW limit: refused, nothing changes */
    assert_int_equal(motion_start_end(&s, 2), ERR_INSTRUCTION);
    assert_int_equal(regs_get(&s.regs, REG_CCW_LIMIT), 700);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(a_stop_is_never_refused_and_drops_the_torque),
        cmocka_unit_test(a_goal_moves_absolute_or_on_the_base_relative),
        cmocka_unit_test(a_goal_is_refused_unloaded_or_unreferenced),
        cmocka_unit_test(speed_turns_in_speed_mode_and_sets_the_cruise_in_a_move),
        cmocka_unit_test(homing_brake_sleep_and_resolution),
        cmocka_unit_test(mirroring_the_motor_forgets_the_reference),
        cmocka_unit_test(clearing_an_unload_only_once_its_cause_is_gone),
        cmocka_unit_test(custom_move_refused_when_it_may_not_start),
        cmocka_unit_test(start_end_sets_the_zero_and_the_end),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
