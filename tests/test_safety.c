/* test_safety.c - heartbeat, protection unload, homing and power-up (PROTOCOL.md §0,
 * §7, §9) on a whole servo driving the host gearmotor model, in virtual time. Faults are
 * injected into the simulated sensors and plant, never into the firmware's state. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "dispatch.h"
#include "write.h"
#include "hal_host.h"
#include "proto.h"
#include "servo.h"
#include "test_rng.h"

static struct hal hal;
static struct servo s;
static uint32_t rng = 7;

static uint32_t rnd(void)
{
    return xorshift32(&rng);
}

static void power_up(const struct board *b)
{
    hal_host_init(&hal);
    hal_host_attach_board(&hal, b);
    hal.now_us = 1000;
    servo_init(&s, b, &hal);
}

/* Advance in steps of one control tick, running the main loop each step. */
static void run_ms(uint32_t ms)
{
    for (uint32_t i = 0; i < ms; i++) {
        hal.now_us += MOTION_TICK_US;
        servo_poll(&s);
    }
}

static uint8_t write8(uint8_t addr, uint8_t v)
{
    return write_registers(&s, addr, &v, 1);
}

static uint8_t write16(uint8_t addr, uint16_t v)
{
    uint8_t d[2] = {(uint8_t)v, (uint8_t)(v >> 8)};
    return write_registers(&s, addr, d, 2);
}

/* A valid PING for this servo through the UART interrupt entry point. */
static void ping(void)
{
    static const uint8_t p[] = {0xD5, 0x5D, 0x01, 0x02, 0x01, 0x04};
    for (size_t i = 0; i < sizeof p; i++)
        servo_rx_isr(&s, p[i]);
    servo_poll(&s);
}

static void speed_mode(uint16_t speed)
{
    assert_int_equal(write16(REG_CCW_LIMIT, 0), 0);
    assert_int_equal(write16(REG_MOVING_SPEED, speed), 0);
}

static bool torque_off(void)
{
    return hal.motor.duty == 0 && !hal.motor.enabled;
}

/* ---- heartbeat ------------------------------------------------------------------------ */

static void heartbeat_randomized(void **state)
{
    (void)state;
    for (int trial = 0; trial < 1000; trial++) {
        bool starve = trial & 1;
        power_up(&board_foot);
        s.regs.mem[REG_RETURN_DELAY] = 0;
        link_latch(&s);
        speed_mode((uint16_t)(30u + rnd() % 300u));
        /* Fed every 0.7 x 500 ms (jittered) for a random time: never trips. Then, when
         * starving, 1.3 x 500 ms of silence: always trips, within one tick of expiry. */
        uint32_t period = 350u - rnd() % 20u;
        uint32_t feeds = 3u + rnd() % 6u;
        for (uint32_t k = 0; k < feeds; k++) {
            ping();
            run_ms(period);
            assert_int_equal(s.motion.mode, MOTION_SPEED);
        }
        ping();
        uint32_t silent = starve ? 650u : 350u;
        uint32_t stopped_at = 0;
        for (uint32_t ms = 1; ms <= silent; ms++) {
            run_ms(1);
            if (!stopped_at && s.motion.mode != MOTION_SPEED)
                stopped_at = ms;
        }
        if (starve) {
            assert_in_range(stopped_at, SAFETY_HEARTBEAT_TICKS, SAFETY_HEARTBEAT_TICKS + 1u);
            run_ms(3000);
            assert_int_equal(s.motion.mode, MOTION_HOLD); /* ramped down, then holds */
            double at = hal.motor.travel;
            run_ms(1000);
            assert_true(hal.motor.travel - at < 0.01); /* nothing moves again by itself */
        } else {
            assert_int_equal(stopped_at, 0);
        }
    }
}

/* ---- protection ---------------------------------------------------------------------- */

enum fault { F_CURRENT, F_SAG, F_SURGE, F_HEAT, F_BLOCKED, F_COUNT };
static const uint8_t fault_bit[F_COUNT] = {ERR_OVER_CURRENT, ERR_UNDER_VOLTAGE,
                                           ERR_OVER_VOLTAGE, ERR_OVER_TEMPERATURE, ERR_STALL};

static void inject(int f, bool on)
{
    switch (f) {
    case F_CURRENT: hal.current_extra_ma = on ? 20000u : 0u; break;
    case F_SAG: hal.supply_mv = on ? 6000u : 12000u; break;
    case F_SURGE: hal.supply_mv = on ? 20000u : 12000u; break;
    case F_HEAT: hal.temperature_dc = on ? 1000 : 250; break;
    default: hal.motor.blocked = on; break;
    }
}

/* Start one of the motion modes on a foot. */
static void start_mode(int mode)
{
    write16(REG_MOVING_SPEED, 120);
    switch (mode) {
    case 0: /* a move */
        write16(REG_GOAL_POSITION, 300);
        break;
    case 1: /* speed mode */
        speed_mode(120);
        break;
    case 2: { /* a trajectory */
        static const uint8_t tw[] = {0xD5, 0x5D, 0x01, 0x0B, 0x0A, 0x02, 0x2C, 0x01, 0x78, 0x00,
                                     0x0A, 0x00, 0x78, 0x00, 0};
        uint8_t p[sizeof tw];
        memcpy(p, tw, sizeof p);
        p[sizeof p - 1] = proto_sum(&p[2], (uint16_t)(sizeof p - 3u));
        for (size_t i = 0; i < sizeof p; i++)
            servo_rx_isr(&s, p[i]);
        servo_poll(&s);
        static const uint8_t ta[] = {0xD5, 0x5D, 0x01, 0x02, 0x0B, 0x0E};
        for (size_t i = 0; i < sizeof ta; i++)
            servo_rx_isr(&s, ta[i]);
        servo_poll(&s);
        break;
    }
    default: /* holding after a short move */
        write16(REG_GOAL_POSITION, 20);
        run_ms(1500);
        break;
    }
}

static void each_fault_in_each_mode(void **state)
{
    (void)state;
    for (int f = 0; f < F_COUNT; f++) {
        for (int mode = 0; mode < 4; mode++) {
            if (f == F_BLOCKED && mode == 3)
                continue; /* a stall needs a commanded motion */
            power_up(&board_foot);
            s.regs.mem[REG_HEARTBEAT_ENABLE] = 0;
            if (f == F_BLOCKED) /* else the jammed motor's current trips first */
                assert_int_equal(write8(REG_CURRENT_LIMIT, 255), 0);
            start_mode(mode);
            run_ms(200);
            assert_false(torque_off());
            inject(f, true);
            /* Torque off in the same tick the condition is detected. */
            uint32_t ms = 0;
            while (!(safety_err(&s.safety) & fault_bit[f]) && ms < 3000u) {
                run_ms(1);
                ms++;
            }
            assert_true(safety_err(&s.safety) & fault_bit[f]);
            assert_true(torque_off());
            if (f == F_CURRENT)
                assert_int_equal(ms, 1); /* no filter on over-current */
            /* Latched; motion refused; clearing refused while the condition lasts. */
            run_ms(100);
            assert_true(safety_err(&s.safety) & fault_bit[f]);
            assert_int_equal(write16(REG_GOAL_POSITION, 100), ERR_INSTRUCTION);
            if (f != F_BLOCKED) /* a jammed shaft that does not move is no longer stalling */
                assert_int_equal(write8(REG_CLEAR_UNLOAD, 1), ERR_INSTRUCTION);
            inject(f, false);
            run_ms(3000);
            assert_true(safety_err(&s.safety) & fault_bit[f]); /* still latched */
            assert_int_equal(write8(REG_CLEAR_UNLOAD, 1), 0);
            assert_false(safety_err(&s.safety) & fault_bit[f]);
            double at = hal.motor.travel;
            run_ms(1000);
            assert_true(torque_off());
            assert_true(hal.motor.travel - at < 0.02); /* nothing until commanded */
            if (mode == 1) /* speed mode: the command is a speed */
                assert_int_equal(write16(REG_MOVING_SPEED, 100), 0);
            else
                assert_int_equal(write16(REG_GOAL_POSITION, 100), 0);
            run_ms(100);
            assert_false(torque_off());
        }
    }
}

static void noise_does_not_trip(void **state)
{
    (void)state;
    power_up(&board_foot);
    s.regs.mem[REG_HEARTBEAT_ENABLE] = 0;
    speed_mode(100);
    for (int i = 0; i < 2000; i++) { /* 1 ms dips to 6 V every 20 ms */
        hal.supply_mv = (i % 20 == 0) ? 6000u : 12000u;
        run_ms(1);
    }
    assert_int_equal(safety_err(&s.safety), 0);
    assert_int_equal(s.motion.mode, MOTION_SPEED);
}

/* ---- homing -------------------------------------------------------------------------- */

static void home_arm(void)
{
    power_up(&board_arm);
    s.regs.mem[REG_HEARTBEAT_ENABLE] = 0;
    assert_int_equal(write8(REG_HOMING, 1), 0);
}

static uint8_t homing_status_now(void)
{
    return (uint8_t)(s.regs.mem[REG_HOMING] >> 4);
}

static void homing_happy_paths(void **state)
{
    (void)state;
    /* Zero side 1: switch 1 at 0, switch 2 at 420 degrees; the arm starts at 90. */
    home_arm();
    assert_int_equal(homing_status_now(), HOMING_STATUS_RUNNING);
    run_ms(12000);
    assert_int_equal(homing_status_now(), HOMING_STATUS_DONE);
    assert_int_equal(regs_get(&s.regs, REG_CW_LIMIT), 0);
    assert_int_equal(regs_get(&s.regs, REG_CCW_LIMIT), 420);
    assert_int_equal(s.motion.mode, MOTION_HOLD);
    assert_int_equal(s.regs.mem[REG_PHOTO_SWITCHES], 2);
    /* Starting on switch 1: back off first. */
    power_up(&board_arm);
    s.regs.mem[REG_HEARTBEAT_ENABLE] = 0;
    hal.motor.theta = -2.0 / 57.29577951308232; /* (placed there: let the speed filter settle) */
    run_ms(300);
    assert_int_equal(s.regs.mem[REG_PHOTO_SWITCHES], 1);
    assert_int_equal(write8(REG_HOMING, 1), 0);
    run_ms(12000);
    assert_int_equal(homing_status_now(), HOMING_STATUS_DONE);
    assert_int_equal(regs_get(&s.regs, REG_CCW_LIMIT), 420);
    /* Zero side 2: the mechanism's zero is at the physical positive end. */
    power_up(&board_arm);
    s.regs.mem[REG_HEARTBEAT_ENABLE] = 0;
    hal.sw1_deg = 420.0;
    hal.sw2_deg = 0.0;
    hal.motor.theta = 300.0 / 57.29577951308232;
    run_ms(300);
    assert_int_equal(write8(REG_HOMING_ZERO_SIDE, 2), 0);
    assert_int_equal(write8(REG_HOMING, 1), 0);
    run_ms(12000);
    assert_int_equal(homing_status_now(), HOMING_STATUS_DONE);
    assert_int_equal(regs_get(&s.regs, REG_CCW_LIMIT), 420);
    /* Moves now count up from the zero toward the end: goal 100 is 320 physical. */
    write16(REG_MOVING_SPEED, 90);
    assert_int_equal(write16(REG_GOAL_POSITION, 100), 0);
    run_ms(8000);
    assert_in_range((uint32_t)(hal.motor.theta * 57.29577951308232 + 0.5), 319, 321);
}

static void homing_fails_on_both_switches_or_a_missing_switch(void **state)
{
    (void)state;
    /* Both switches at once. */
    home_arm();
    hal.photo_sim = false;
    hal.photo = 3;
    run_ms(100);
    assert_int_equal(homing_status_now(), HOMING_STATUS_FAILED);
    /* Switch 2 never found within the board's travel. */
    home_arm();
    hal.sw2_deg = 5000.0;
    run_ms(30000);
    assert_int_equal(homing_status_now(), HOMING_STATUS_FAILED);
    /* Stall while seeking. */
    home_arm();
    run_ms(300);
    hal.motor.blocked = true;
    run_ms(2000);
    assert_int_equal(homing_status_now(), HOMING_STATUS_FAILED);
    /* No switches on this board. */
    power_up(&board_foot);
    assert_int_equal(write8(REG_HOMING, 1), 0);
    assert_int_equal(homing_status_now(), HOMING_STATUS_FAILED);
    /* A failure leaves no reference: moves stay refused. */
    home_arm();
    hal.motor.blocked = true;
    run_ms(2000);
    assert_int_equal(homing_status_now(), HOMING_STATUS_FAILED);
    hal.motor.blocked = false;
    assert_int_equal(write8(REG_CLEAR_UNLOAD, 1), 0);
    assert_int_equal(write16(REG_GOAL_POSITION, 100), ERR_INSTRUCTION);
}

/* Aborts from each phase: back-off, seek, reverse. */
static void homing_aborted_in_any_phase_reads_failed_and_refuses_moves(void **state)
{
    (void)state;
    static const uint32_t phase_ms[] = {20, 500, 3000};
    for (int abort_kind = 0; abort_kind < 5; abort_kind++) {
        for (int ph = 0; ph < 3; ph++) {
            power_up(&board_arm);
            if (ph == 0)
                hal.motor.theta = -2.0 / 57.29577951308232;
            run_ms(300);
            s.regs.mem[REG_HEARTBEAT_ENABLE] = abort_kind == 4;
            assert_int_equal(write8(REG_HOMING, 1), 0);
            run_ms(phase_ms[ph]);
            if (abort_kind != 4)
                assert_int_equal(s.motion.home.phase, ph);
            switch (abort_kind) {
            case 0: assert_int_equal(write8(REG_HOMING, 0), 0); break;
            case 1: assert_int_equal(write16(REG_MOVING_SPEED, 0), 0); break;
            case 2: assert_int_equal(write8(REG_BRAKE, 1), 0); break;
            case 3: hal.current_extra_ma = 20000; break;
            default: break; /* heartbeat: no packet since power-up */
            }
            run_ms(abort_kind == 4 ? 600 : 5);
            assert_int_equal(homing_status_now(), HOMING_STATUS_FAILED);
            assert_int_not_equal(s.motion.mode, MOTION_HOME);
            assert_int_equal(write16(REG_GOAL_POSITION, 100), ERR_INSTRUCTION);
        }
    }
}

/* ---- power-up ------------------------------------------------------------------------ */

static void power_cycles_never_move(void **state)
{
    (void)state;
    hal_host_init(&hal);
    for (int cycle = 0; cycle < 1000; cycle++) {
        if (cycle % 3 == 0) /* now and then the flash is garbage */
            for (size_t i = 0; i < sizeof hal.flash.mem; i += 1u + rnd() % 64u)
                ((uint8_t *)hal.flash.mem)[i] = (uint8_t)rnd();
        hal_host_reboot(&hal);
        servo_init(&s, cycle & 1 ? &board_arm : &board_foot, &hal);
        /* The shaft may still be coasting from before the cut; the firmware must not add
         * to it: no drive, and the speed never grows. */
        double w = hal.motor.omega < 0 ? -hal.motor.omega : hal.motor.omega;
        for (int ms = 0; ms < 50; ms++) {
            run_ms(1);
            assert_true(torque_off());
            double w2 = hal.motor.omega < 0 ? -hal.motor.omega : hal.motor.omega;
            assert_true(w2 <= w + 1e-9);
            w = w2;
        }
        assert_int_equal(regs_get(&s.regs, REG_GOAL_POSITION), regs_present_position(&s.regs));
        assert_int_equal(s.regs.mem[REG_MOVING], 0);
        if (cycle % 10 == 0) { /* some cycles end mid-motion, like a brown-out */
            write8(REG_MOVE_WITHOUT_REFERENCE, 1);
            speed_mode(200);
            run_ms(20);
        }
    }
}

/* ---- the port's fittings ---------------------------------------------------------- */

/* Power up b on a port that reports its fittings less those in lack. */
static void power_up_lacking(const struct board *b, uint8_t lack)
{
    hal_host_init(&hal);
    hal_host_attach_board(&hal, b);
    hal.capabilities &= (uint8_t)~lack;
    hal.now_us = 1000;
    servo_init(&s, b, &hal);
    s.regs.mem[REG_HEARTBEAT_ENABLE] = 0;
    assert_int_equal(write16(REG_MOVING_SPEED, 120), 0);
}

/* The port reports its fittings (hal_capabilities) and the core checks the board's
 * against them at start: on a port without the foot's encoder or terminator the servo
 * refuses every move with ERR bit 5 and keeps the motor off, and register 25 does not
 * lift that; the arm on a port without photo switches refuses to home. A fitting
 * the board does not need (the foot's switches, the pot) changes nothing. */
static void a_port_without_the_boards_fittings_never_moves(void **state)
{
    (void)state;
    static const uint8_t lack[] = {HAL_CAP_ENCODER, HAL_CAP_TERMINATOR};
    for (size_t i = 0; i < sizeof lack; i++) {
        power_up_lacking(&board_foot, lack[i]);
        assert_int_equal(write16(REG_GOAL_POSITION, 100), ERR_INSTRUCTION);
        assert_int_equal(write8(REG_CLEAR_UNLOAD, 1), 0);
        assert_int_equal(write16(REG_GOAL_POSITION, 100), ERR_INSTRUCTION);
        run_ms(200);
        assert_true(torque_off());
    }
    power_up_lacking(&board_foot, HAL_CAP_PHOTO | HAL_CAP_POT);
    assert_int_equal(write16(REG_GOAL_POSITION, 100), 0);
    run_ms(200);
    assert_false(torque_off());

    power_up_lacking(&board_arm, HAL_CAP_PHOTO);
    assert_int_equal(write8(REG_HOMING, 1), ERR_INSTRUCTION);
    run_ms(20);
    assert_int_not_equal(homing_status_now(), HOMING_STATUS_RUNNING);
    assert_true(torque_off());
    power_up_lacking(&board_arm, HAL_CAP_POT);
    assert_int_equal(write8(REG_HOMING, 1), 0);
    run_ms(20);
    assert_int_equal(homing_status_now(), HOMING_STATUS_RUNNING);
    assert_false(torque_off());
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(heartbeat_randomized),
        cmocka_unit_test(a_port_without_the_boards_fittings_never_moves),
        cmocka_unit_test(each_fault_in_each_mode),
        cmocka_unit_test(noise_does_not_trip),
        cmocka_unit_test(homing_happy_paths),
        cmocka_unit_test(homing_fails_on_both_switches_or_a_missing_switch),
        cmocka_unit_test(homing_aborted_in_any_phase_reads_failed_and_refuses_moves),
        cmocka_unit_test(power_cycles_never_move),
    };
    return cmocka_run_group_tests(tests, 0, 0);
}
