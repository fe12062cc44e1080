/* test_register_effects.c - every writable register acts (issue 25: register 20, the RS485
 * terminator, was validated and stored but did nothing). For each one, a write changes what
 * the servo does or reports, seen through the bus (tests/bus_host.h) and the host HAL's
 * outputs (the bridge, the plant, the terminator); and every writable register of the table
 * has such a test here and an owner in write.h's hooks, so a register added without an
 * effect fails this test. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "bus_host.h"
#include "write.h"

#define RAD_TO_DEG 57.29577951308232

static double shaft_deg(void)
{
    struct hal *h = bus_hal();
    motor_sim_advance(&h->motor, bus.now_us);
    return h->motor.theta * RAD_TO_DEG;
}

static double shaft_dps(void)
{
    struct hal *h = bus_hal();
    motor_sim_advance(&h->motor, bus.now_us);
    return h->motor.omega * RAD_TO_DEG;
}

/* The ERR bits of an answer among bits (no answer fails). */
static unsigned err_bits(int e, unsigned bits)
{
    assert_true(e >= 0);
    return (unsigned)e & bits;
}

static uint8_t read8(uint8_t addr)
{
    uint8_t p[2] = {addr, 1};
    assert_int_equal(err_bits(bus_ins(INS_READ, p, 2), ERR_INSTRUCTION | ERR_CHECKSUM), 0);
    return bus_ans[0];
}

static uint16_t read16(uint8_t addr)
{
    uint8_t p[2] = {addr, 2};
    assert_int_equal(err_bits(bus_ins(INS_READ, p, 2), ERR_INSTRUCTION | ERR_CHECKSUM), 0);
    return (uint16_t)(bus_ans[0] | bus_ans[1] << 8);
}

static int32_t position(const struct board *b)
{
    uint8_t t[REGS_SIZE];
    assert_true(bus_read_table(t));
    return tab_position(b, t);
}

/* Keep the heartbeat fed for ms (a PING every 100 ms). */
static void talk_ms(uint32_t ms)
{
    for (uint32_t t = 0; t < ms; t += 100u) {
        bus_run_ms(100);
        assert_int_equal(bus_ins(INS_PING, NULL, 0), 1);
    }
}

/* When the answer to the last packet began, after that packet's end (us). */
static uint32_t answer_after_us(uint32_t wire_from)
{
    uint32_t host_end = 0;
    for (uint32_t i = wire_from; i < bus.wire_len; i++) {
        const struct vbus_byte *b = vbus_wire(&bus, i);
        if (b->src == VBUS_HOST)
            host_end = b->end_us;
        else
            return b->start_us - host_end;
    }
    fail_msg("no answer on the wire");
    return 0;
}

/* ---- one test per writable register ------------------------------------------------- */

static void id_3(void)
{
    assert_true(bus_open(&board_foot));
    assert_int_equal(bus_w8(REG_ID, 7), 0); /* answered at ID 1, then in force */
    assert_int_equal(bus_ins_to(7, INS_PING, NULL, 0), 1);
    assert_int_equal(bus_ins_to(1, INS_PING, NULL, 0), -1);
}

static void baud_4(void)
{
    assert_true(bus_open(&board_foot));
    assert_int_equal(bus_w8(REG_BAUD_RATE, 4), 0); /* 115200, answered at 1.79 Mbaud */
    bus_run_ms(1);
    assert_int_equal(bus_ins(INS_PING, NULL, 0), -1); /* the host still at 1.79 Mbaud */
    bus.host_baud = 115200;
    assert_int_equal(bus_ins(INS_PING, NULL, 0), 1);
}

static void return_delay_5(void)
{
    assert_true(bus_open(&board_foot));
    uint32_t from = bus.wire_len;
    assert_int_equal(bus_ins(INS_PING, NULL, 0), 1);
    uint32_t fast = answer_after_us(from);
    assert_int_equal(bus_w8(REG_RETURN_DELAY, 10), 0); /* 5 ms */
    from = bus.wire_len;
    assert_int_equal(bus_ins(INS_PING, NULL, 0), 1);
    uint32_t slow = answer_after_us(from);
    assert_true(fast < 500u);
    assert_true(slow >= 5000u && slow < 5500u);
}

static void limits_6_8(void)
{
    assert_true(bus_open(&board_foot));
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 180), 0);
    const uint8_t lim[4] = {20, 0, 100, 0};
    assert_int_equal(bus_write(REG_CW_LIMIT, lim, 4), 0);
    assert_int_equal(bus_w16(REG_GOAL_POSITION, 300), 0);
    assert_int_equal(read16(REG_GOAL_POSITION), 100); /* clamped */
    talk_ms(2000);
    assert_int_equal(position(&board_foot), 100);
    assert_true(fabs(shaft_deg() - 100.0) < 0.5);
    assert_int_equal(bus_w16(REG_GOAL_POSITION, 0), 0);
    talk_ms(2000);
    assert_int_equal(position(&board_foot), 20);
}

static void temperature_limit_11(void)
{
    assert_true(bus_open(&board_foot));
    bus_hal()->temperature_dc = 500; /* 50 C: under the factory 80 */
    talk_ms(1000);
    assert_int_equal(bus_ins(INS_PING, NULL, 0), 1);
    assert_int_equal(bus_ans[0] & ERR_OVER_TEMPERATURE, 0);
    assert_int_equal(bus_w8(REG_TEMPERATURE_LIMIT, 40), 0);
    talk_ms(1000);
    assert_int_equal(bus_ins(INS_PING, NULL, 0), 1);
    assert_int_equal(bus_ans[0] & ERR_OVER_TEMPERATURE, ERR_OVER_TEMPERATURE);
}

static void current_limit_12(void)
{
    assert_true(bus_open(&board_foot));
    bus_hal()->current_extra_ma = 3000; /* 3 A: under the foot's 4 A */
    talk_ms(300);
    assert_int_equal(bus_ins(INS_PING, NULL, 0), 1);
    assert_int_equal(bus_ans[0] & ERR_OVER_CURRENT, 0);
    assert_int_equal(bus_w8(REG_CURRENT_LIMIT, 20), 0); /* 2 A */
    talk_ms(300);
    assert_int_equal(bus_ins(INS_PING, NULL, 0), 1);
    assert_int_equal(bus_ans[0] & ERR_OVER_CURRENT, ERR_OVER_CURRENT);
}

static void resolution_13(void)
{
    assert_true(bus_open(&board_foot));
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 180), 0);
    assert_int_equal(bus_w16(REG_GOAL_POSITION, 90), 0);
    talk_ms(1500);
    assert_int_equal(position(&board_foot), 90);
    assert_int_equal(bus_w8(REG_RESOLUTION, 1), 0); /* 0.1 degree */
    assert_int_equal(position(&board_foot), 900);
    assert_int_equal(read16(REG_CCW_LIMIT), 3600);
}

static void status_level_16(void)
{
    assert_true(bus_open(&board_foot));
    assert_int_equal(bus_w8(REG_STATUS_RETURN_LEVEL, 1), 0); /* answered at level 2 */
    assert_int_equal(bus_w8(REG_ACCELERATION, 20), -1);      /* executed, not answered */
    assert_int_equal(read8(REG_ACCELERATION), 20);
}

static void heartbeat_17(void)
{
    assert_true(bus_open(&board_base));
    assert_int_equal(bus_w8(REG_HEARTBEAT_ENABLE, 0), 0);
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 360), 0);
    bus_run_ms(2000); /* silent */
    assert_true(shaft_dps() > 300.0);
    assert_int_equal(bus_w8(REG_HEARTBEAT_ENABLE, 1), 0);
    bus_run_ms(2000); /* silent: the heartbeat stops it (§7.1) */
    assert_true(fabs(shaft_dps()) < 1.0);
}

static void unload_conditions_18(void)
{
    assert_true(bus_open(&board_base));
    assert_int_equal(bus_w8(REG_UNLOAD_CONDITIONS, 0x7E), 0); /* not on over-temperature */
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 360), 0);
    bus_hal()->temperature_dc = 1000;
    talk_ms(1500);
    assert_int_equal(bus_ins(INS_PING, NULL, 0), 1);
    assert_int_equal(bus_ans[0] & ERR_OVER_TEMPERATURE, ERR_OVER_TEMPERATURE); /* reported */
    assert_true(bus_hal()->motor.enabled && shaft_dps() > 300.0);            /* turning on */
    assert_int_equal(err_bits(bus_w8(REG_UNLOAD_CONDITIONS, 0x7F), ERR_INSTRUCTION), 0);
    talk_ms(300);
    assert_false(bus_hal()->motor.enabled); /* unloaded */
    /* bits 4 and 5: the errors are answered, or not */
    const uint8_t bad_sub = 0x7F;
    assert_int_equal(err_bits(bus_ins(INS_CUSTOM, &bad_sub, 1), ERR_INSTRUCTION), ERR_INSTRUCTION);
    assert_int_equal(err_bits(bus_w8(REG_UNLOAD_CONDITIONS, 0x5F), ERR_INSTRUCTION), 0);
    assert_int_equal(bus_ins(INS_CUSTOM, &bad_sub, 1), -1);
}

static void zero_side_19(void)
{
    assert_true(bus_open(&board_foot));
    assert_int_equal(bus_w8(REG_HEARTBEAT_ENABLE, 0), 0);
    const uint8_t wheel[4] = {0, 0, 0, 0};
    assert_int_equal(bus_write(REG_CW_LIMIT, wheel, 4), 0);
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 90), 0);
    bus_run_ms(1000);
    assert_true(shaft_dps() > 80.0);
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 0), 0);
    assert_int_equal(bus_w8(REG_HOMING_ZERO_SIDE, 2), 0); /* the motor mirrored (§9) */
    bus_run_ms(1500);
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 90), 0); /* positive now turns the plant back */
    bus_run_ms(1000);
    assert_true(shaft_dps() < -80.0);
}

/* Issue 25: register 20 was kept in flash and did nothing. It switches the terminator once
 * the answer to its write has left the wire (§1), and at power-up from flash. */
static void terminator_20(void)
{
    assert_true(bus_open(&board_foot));
    assert_false(bus_hal()->termination);
    assert_int_equal(bus_w8(REG_RS485_TERMINATION, 1), 0);
    assert_true(bus_hal()->termination);
    vbus_power_cycle(&bus, 0);
    bus_run_ms(10);
    assert_true(bus_hal()->termination); /* from flash */
    bus.host_baud = board_foot.default_baud; /* the fast link was not in flash yet? */
    if (bus_ins(INS_PING, NULL, 0) != 1)
        bus.host_baud = BUS_FAST_BAUD;
    assert_int_equal(bus_w8(REG_RS485_TERMINATION, 0), 0);
    assert_false(bus_hal()->termination);
}

/* The ramp registers of a variant: 21/22 on the base, 34/35 elsewhere. */
static void ramps(const struct board *b, uint8_t acc)
{
    assert_true(bus_open(b));
    const uint8_t wheel[4] = {0, 0, 0, 0};
    if (b->variant != VARIANT_BASE)
        assert_int_equal(bus_write(REG_CW_LIMIT, wheel, 4), 0);
    assert_int_equal(bus_w8(acc, 5), 0); /* 50 deg/s^2 */
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 360), 0);
    talk_ms(1000);
    double slow = shaft_dps(); /* about 50 deg/s after 1 s */
    assert_true(slow > 30.0 && slow < 70.0);
    assert_int_equal(bus_w8((uint8_t)(acc + 1u), 5), 0); /* deceleration 50 deg/s^2 */
    assert_int_equal(bus_w8(acc, 0), 0);                 /* no ramp: full speed at once */
    talk_ms(500);
    assert_true(shaft_dps() > 300.0);
    bus_run_ms(1500); /* silent: the heartbeat ramps down at the deceleration */
    double stopping = shaft_dps(); /* 1 s of braking at 50 deg/s^2 from 360 */
    assert_true(stopping > 250.0 && stopping < 350.0);
}

static void base_ramps_21_22(void)
{
    ramps(&board_base, REG_BASE_ACCELERATION);
}

static void ramps_34_35(void)
{
    ramps(&board_foot, REG_ACCELERATION);
}

static void homing_24(void)
{
    assert_true(bus_open(&board_arm));
    assert_int_equal(bus_w8(REG_HOMING, 1), 0);
    bus_run_ms(100);
    assert_int_equal(read8(REG_HOMING), 0x11); /* running */
    assert_int_equal(bus_w8(REG_HOMING, 0), 0);  /* aborted */
    assert_int_equal(read8(REG_HOMING), 0x30);
    assert_int_equal(bus_home(20000), 2);
}

static void clear_unload_25(void)
{
    assert_true(bus_open(&board_foot));
    bus_hal()->current_extra_ma = 6000;
    talk_ms(200);
    bus_hal()->current_extra_ma = 0;
    talk_ms(200);
    assert_int_equal(err_bits(bus_w16(REG_GOAL_POSITION, 50), ERR_INSTRUCTION), ERR_INSTRUCTION);
    assert_int_equal(bus_w8(REG_CLEAR_UNLOAD, 1), 0);
    assert_int_equal(bus_ins(INS_PING, NULL, 0), 1);
    assert_int_equal(bus_ans[0], 0);
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 90), 0);
    assert_int_equal(bus_w16(REG_GOAL_POSITION, 50), 0); /* motion accepted again */
}

static void goal_30(void)
{
    assert_true(bus_open(&board_foot));
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 180), 0);
    assert_int_equal(bus_w16(REG_GOAL_POSITION, 45), 0);
    talk_ms(1500);
    assert_int_equal(position(&board_foot), 45);
    assert_true(fabs(shaft_deg() - 45.0) < 0.5);
}

static void speed_32(void)
{
    assert_true(bus_open(&board_base));
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 0x8000u | 200u), 0);
    talk_ms(1500);
    assert_true(shaft_dps() < -180.0);
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 0), 0);
    assert_false(bus_hal()->motor.enabled); /* rule 3: a stop without torque */
}

static void brake_43(void)
{
    assert_true(bus_open(&board_base));
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 360), 0);
    talk_ms(1000);
    assert_int_equal(bus_w8(REG_BRAKE, 1), 0);
    talk_ms(500);
    assert_true(bus_hal()->motor.enabled && fabs(shaft_dps()) < 1.0); /* held */
}

static void sleep_47(void)
{
    assert_true(bus_open(&board_foot));
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 90), 0);
    assert_int_equal(bus_w16(REG_GOAL_POSITION, 300), 0);
    talk_ms(300);
    assert_true(bus_hal()->motor.enabled);
    assert_int_equal(bus_w8(REG_SLEEP, 1), 0);
    assert_false(bus_hal()->motor.enabled); /* torque off */
}

static void move_without_reference_49(void)
{
    assert_true(bus_open(&board_arm)); /* not homed */
    const uint8_t wheel[4] = {0, 0, 0, 0};
    assert_int_equal(bus_write(REG_CW_LIMIT, wheel, 4), 0);
    assert_int_equal(err_bits(bus_w16(REG_MOVING_SPEED, 30), ERR_INSTRUCTION), ERR_INSTRUCTION);
    assert_int_equal(bus_w8(REG_MOVE_WITHOUT_REFERENCE, 1), 0);
    assert_int_equal(bus_w16(REG_MOVING_SPEED, 30), 0);
    talk_ms(1000);
    assert_true(shaft_dps() > 20.0);
}

static const struct {
    uint8_t addr;
    void (*check)(void);
    const char *name;
} effects[] = {
    {REG_ID, id_3, "id"},
    {REG_BAUD_RATE, baud_4, "baud"},
    {REG_RETURN_DELAY, return_delay_5, "return delay"},
    {REG_CW_LIMIT, limits_6_8, "CW limit"},
    {REG_CCW_LIMIT, limits_6_8, "CCW limit"},
    {REG_TEMPERATURE_LIMIT, temperature_limit_11, "temperature limit"},
    {REG_CURRENT_LIMIT, current_limit_12, "current limit"},
    {REG_RESOLUTION, resolution_13, "resolution"},
    {REG_STATUS_RETURN_LEVEL, status_level_16, "status return level"},
    {REG_HEARTBEAT_ENABLE, heartbeat_17, "heartbeat"},
    {REG_UNLOAD_CONDITIONS, unload_conditions_18, "unload conditions"},
    {REG_HOMING_ZERO_SIDE, zero_side_19, "homing zero side"},
    {REG_RS485_TERMINATION, terminator_20, "RS485 terminator"},
    {REG_BASE_ACCELERATION, base_ramps_21_22, "base acceleration"},
    {REG_BASE_DECELERATION, base_ramps_21_22, "base deceleration"},
    {REG_HOMING, homing_24, "homing"},
    {REG_CLEAR_UNLOAD, clear_unload_25, "clear unload"},
    {REG_GOAL_POSITION, goal_30, "goal"},
    {REG_MOVING_SPEED, speed_32, "speed"},
    {REG_ACCELERATION, ramps_34_35, "acceleration"},
    {REG_DECELERATION, ramps_34_35, "deceleration"},
    {REG_BRAKE, brake_43, "brake"},
    {REG_SLEEP, sleep_47, "sleep"},
    {REG_MOVE_WITHOUT_REFERENCE, move_without_reference_49, "move without reference"},
};

static void every_writable_register_acts(void **state)
{
    (void)state;
    uint64_t done = 0;
    for (size_t i = 0; i < sizeof effects / sizeof effects[0]; i++) {
        print_message("register %2u (%s)\n", effects[i].addr, effects[i].name);
        effects[i].check();
        done |= (uint64_t)1 << effects[i].addr;
    }
    for (uint8_t a = 0; a < REGS_SIZE; a++) {
        const struct reg_desc *d = &regs_table[a];
        if (!d->size || !(d->access & REG_ACCESS_W))
            continue;
        if (!((done >> a) & 1u))
            fail_msg("register %u (%s) is writable but no test here shows what it does", a,
                     d->name);
        uint64_t owned = 0;
        for (uint8_t h = 0; h < write_hook_count; h++)
            owned |= write_hooks[h].acts_on | write_hooks[h].reads;
        if (!((owned >> a) & 1u))
            fail_msg("register %u (%s) is writable but no module acts on it (write.c)", a,
                     d->name);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(every_writable_register_acts),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
