/* test_motion.c - the motion layer closed-loop on the host gearmotor (PROTOCOL.md §0,
 * §4.6-§4.8, §5.4, §6; issue 5): one servo on the host HAL, virtual time advanced in
 * 250 us steps through servo_poll(), commands through write_registers() (register writes)
 * and dispatch_frame() (instructions), motor state read from s.motion, s.regs and
 * hal.motor.
 *
 * Setup common to every test: heartbeat off (register 17 := 0; these tests stay quiet
 * for seconds, and the heartbeat would rightly stop the motor after 500 ms, §7.1) and
 * return delay 0. Arm, wrist and finger have photo switches: they are homed first
 * (register 24 := 1, §9), which gives them limits 0..420 / 0..270 / 0..180.
 *
 * Bounds (counts are encoder counts, 16384 per turn, 45.5 per degree):
 *   tracking error |reference - measured| during a move  <= TRACK_MAX_COUNTS
 *   overshoot past the goal                                <= OVERSHOOT_MAX_COUNTS
 *   settle: from the reference at rest to |error| <= 1 count for good  <= SETTLE_MAX_MS
 *   reference duration <= d/v + v/(2a) + v/(2d) (or the triangle) + MOVE_SLACK_MS
 *   end: the present-position register equals the goal exactly. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "dispatch.h"
#include "write.h"
#include "hal_host.h"
#include "proto.h"
#include "servo.h"
#include "test_rng.h"

#define STEP_US 250u
#define CPR 16384.0
#define COUNTS_PER_DEG (CPR / 360.0)
#define RAD_TO_DEG 57.29577951308232

#define TRACK_MAX_COUNTS 23.0    /* 0.5 degree: half a position unit at resolution 10 */
#define OVERSHOOT_MAX_COUNTS 4.0 /* 0.09 degree */
#define SETTLE_MAX_MS 100.0
#define MOVE_SLACK_MS 2.0 /* reference duration <= continuous optimum + 2 ticks (the */
                          /* command lands between ticks; the planner's own tick)  */

static struct hal hal;
static struct servo s;
static const struct board *B;

/* --- random numbers (xorshift32), seeded per test ----------------------------------- */
static uint32_t rng = 1;
static uint32_t rnd(uint32_t n)
{
    return xorshift32(&rng) % n;
}

/* --- time ---------------------------------------------------------------------------- */
static void step(void)
{
    hal.now_us += STEP_US;
    servo_poll(&s);
}

static void run_ms(uint32_t ms)
{
    for (uint32_t i = 0; i < ms * 1000u / STEP_US; i++)
        step();
}

/* Advance to just after the next control tick. */
static void next_tick(void)
{
    uint32_t t = s.motion.tick_us;
    while (s.motion.tick_us == t)
        step();
}

/* --- commands ------------------------------------------------------------------------ */
static uint8_t wr(uint8_t addr, const uint8_t *d, uint8_t n)
{
    return write_registers(&s, addr, d, n);
}

static void w8(uint8_t addr, uint8_t v)
{
    if (wr(addr, &v, 1))
        fail_msg("write %u := %u refused", addr, v);
}

static void w16(uint8_t addr, uint16_t v)
{
    uint8_t d[2] = {(uint8_t)v, (uint8_t)(v >> 8)};
    if (wr(addr, d, 2))
        fail_msg("write %u := %u refused", addr, v);
}

/* Limits (6-9) in one write, so CW <= CCW holds after it. */
static void w_limits(uint16_t cw, uint16_t ccw)
{
    uint8_t d[4] = {(uint8_t)cw, (uint8_t)(cw >> 8), (uint8_t)ccw, (uint8_t)(ccw >> 8)};
    if (wr(REG_CW_LIMIT, d, 4))
        fail_msg("limits %u..%u refused", cw, ccw);
}

/* An instruction frame to this servo through the dispatcher, as the main loop hands it
 * over; returns the ERR byte of the answer it schedules. */
static uint8_t cmd(uint8_t ins, const uint8_t *p, uint8_t n)
{
    static struct frame f;
    static uint8_t buf[FRAME_BYTES];
    memset(&f, 0, sizeof f);
    f.buf = buf;
    f.buf[0] = s.link.id;
    f.buf[1] = (uint8_t)(n + 2u);
    f.buf[2] = ins;
    if (n)
        memcpy(&f.buf[3], p, n);
    f.buf[3u + n] = proto_sum(f.buf, (uint16_t)(n + 3u));
    f.len = (uint16_t)(n + 4u);
    f.status = FRAME_OK;
    f.end_us = hal.now_us;
    s.link.state = LINK_IDLE; /* the previous answer, if any, has long been sent */
    dispatch_frame(&s, &f);
    if (regs_take_ee_changed(&s.regs)) /* as servo_poll() does at the end of its pass */
        store_sync(&s.store, &s.regs, hal.now_us);
    assert_int_equal(s.link.state, LINK_WAITING);
    return s.link.tx[4];
}

static uint8_t start_end(uint8_t what)
{
    return cmd(INS_START_END, &what, 1);
}

static uint8_t custom_rel(uint16_t rel, uint16_t speed, int ramps, uint8_t acc, uint8_t dec)
{
    uint8_t p[7] = {1, (uint8_t)rel, (uint8_t)(rel >> 8), (uint8_t)speed, (uint8_t)(speed >> 8),
                    acc, dec};
    return cmd(INS_CUSTOM, p, ramps ? 7 : 5);
}

static uint8_t custom_abs(uint16_t pos, uint16_t speed, uint8_t acc, uint8_t dec)
{
    uint8_t p[7] = {2, (uint8_t)pos, (uint8_t)(pos >> 8), (uint8_t)speed, (uint8_t)(speed >> 8),
                    acc, dec};
    return cmd(INS_CUSTOM, p, 7);
}

/* TRAJECTORY WRITE of n points (angle, speed), 4-byte form if four, else 3-byte. */
static uint8_t traj_write_pts(const uint16_t *angle, const uint16_t *speed, uint8_t n, int four)
{
    uint8_t p[256];
    uint8_t k = 0;
    p[k++] = n;
    for (uint8_t i = 0; i < n; i++) {
        p[k++] = (uint8_t)angle[i];
        p[k++] = (uint8_t)(angle[i] >> 8);
        p[k++] = (uint8_t)speed[i];
        if (four)
            p[k++] = (uint8_t)(speed[i] >> 8);
    }
    return cmd(INS_TRAJ_WRITE, p, k);
}

static uint8_t traj_action(void)
{
    return cmd(INS_TRAJ_ACTION, NULL, 0);
}

/* --- state ----------------------------------------------------------------------------- */
static bool wh(void)
{
    return B->variant == VARIANT_WRIST || B->variant == VARIANT_FINGER;
}

/* The present position in units (regs_position_addr(), regs.h). */
static int32_t present(void)
{
    uint8_t a = regs_position_addr(B);
    return regs_position_value(a, regs_get(&s.regs, a));
}

static int32_t present_speed(void)
{
    return (int16_t)regs_get(&s.regs, REG_PRESENT_SPEED);
}

static double shaft_deg(void)
{
    return hal.motor.theta * RAD_TO_DEG;
}

static double omega_dps(void)
{
    return hal.motor.omega * RAD_TO_DEG;
}

static double travel_counts(void)
{
    return hal.motor.travel / (2.0 * 3.14159265358979323846) * CPR;
}

static int64_t ref_counts(void)
{
    return (s.motion.plan.pos + PLANNER_ONE / 2) >> PLANNER_SHIFT;
}

/* --- power-up -------------------------------------------------------------------------- */
static void power_up(const struct board *b)
{
    B = b;
    hal_host_init(&hal);
    hal_host_attach_board(&hal, b);
    servo_init(&s, b, &hal);
}

static void quiet_setup(void)
{
    w8(REG_HEARTBEAT_ENABLE, 0);
    w8(REG_RETURN_DELAY, 0);
}

/* Homing (§9) on boards with photo switches; a reference is what position moves need. */
static void home(void)
{
    if (!B->photo_switches)
        return;
    w8(REG_HOMING, 1);
    for (int i = 0; i < 20000 && (s.regs.mem[REG_HOMING] >> 4) == 1u; i++)
        run_ms(1);
    if ((s.regs.mem[REG_HOMING] >> 4) != 2u)
        fail_msg("%s: homing did not succeed (register 24 = 0x%02x)", B->name,
                 s.regs.mem[REG_HOMING]);
    run_ms(300);
}

/* A powered-up, quiet, homed servo of board b; homing runs once per board, later calls
 * restore a snapshot of servo and plant. Kept per board, not per variant: two boards of
 * one variant differ in their limits and fittings (a sixth board, issue 28). */
static struct servo snap_s[BOARD_COUNT];
static struct hal snap_h[BOARD_COUNT];
static bool snap_ok[BOARD_COUNT];

static unsigned board_no(const struct board *b)
{
    unsigned i = 0;
    while (i + 1u < BOARD_COUNT && board_all[i] != b)
        i++;
    assert_ptr_equal(board_all[i], b);
    return i;
}

static void ready(const struct board *b)
{
    unsigned i = board_no(b);
    if (snap_ok[i]) {
        B = b;
        hal = snap_h[i];
        s = snap_s[i];
        s.hal = &hal;
        return;
    }
    power_up(b);
    quiet_setup();
    home();
    snap_s[i] = s;
    snap_h[i] = hal;
    snap_ok[i] = true;
}


/* --- a measured move ------------------------------------------------------------------- */
struct move_result {
    double track;     /* counts, max |reference - measured| while the reference moves */
    double overshoot; /* counts past the goal */
    double settle_ms; /* reference at rest -> within 1 count for good */
    double move_ms;   /* command -> reference at rest */
    double ideal_ms;  /* continuous optimum of the trapezoid */
    double peak_dps;  /* highest measured speed */
};

static double ideal_ms(double dist_deg, double v, double a, double d)
{
    if (a <= 0)
        a = 1e12;
    if (d <= 0)
        d = 1e12;
    if (dist_deg >= v * v / (2 * a) + v * v / (2 * d))
        return 1000.0 * (dist_deg / v + v / (2 * a) + v / (2 * d));
    double vp = sqrt(2 * dist_deg * a * d / (a + d));
    return 1000.0 * (vp / a + vp / d);
}

/* After a command that started a move: follow it to rest and 400 ms beyond. */
static struct move_result follow_move(double speed_dps, double acc, double dec)
{
    struct move_result r = {0};
    if (s.motion.mode != MOTION_MOVE)
        fail_msg("%s: the move did not start (mode %u)", B->name, s.motion.mode);
    int64_t g = s.motion.target / PLANNER_ONE;
    assert_true(g * PLANNER_ONE == s.motion.target); /* whole counts */
    int64_t c0 = ref_counts(); /* the reference moves from where it held (the shaft may
                                  rest a count off it: CONTROL_HOLD_BAND) */
    int dir = g > c0 ? 1 : -1;
    uint32_t t0 = hal.now_us, t_end = 0, t_out = 0;
    r.ideal_ms = ideal_ms(fabs((double)(g - c0)) / COUNTS_PER_DEG, speed_dps, acc, dec);
    uint32_t limit_us = (uint32_t)(r.ideal_ms * 1000.0 * 2.0) + 2000000u;
    for (;;) {
        next_tick();
        uint32_t t = hal.now_us;
        int64_t err = s.motion.ctl.counts - g;
        if (s.motion.mode == MOTION_MOVE) {
            double e = fabs((double)(ref_counts() - s.motion.ctl.counts));
            if (e > r.track)
                r.track = e;
        } else if (!t_end) {
            t_end = t;
        }
        if ((double)(err * dir) > r.overshoot)
            r.overshoot = (double)(err * dir);
        if (fabs(omega_dps()) > r.peak_dps)
            r.peak_dps = fabs(omega_dps());
        if (t_end && (err > 1 || err < -1))
            t_out = t;
        if (t_end && t - t_end >= 400000u)
            break;
        if (t - t0 > limit_us)
            fail_msg("%s: move to %lld counts not done in %u ms", B->name, (long long)g,
                     limit_us / 1000u);
    }
    r.move_ms = (t_end - t0) / 1000.0;
    r.settle_ms = t_out ? (t_out - t_end) / 1000.0 + 1.0 : 0.0;
    return r;
}

static struct move_result worst;
static void note(const struct move_result *r)
{
    if (r->track > worst.track)
        worst.track = r->track;
    if (r->overshoot > worst.overshoot)
        worst.overshoot = r->overshoot;
    if (r->settle_ms > worst.settle_ms)
        worst.settle_ms = r->settle_ms;
}

static void check_move(const struct move_result *r, int32_t goal_units, const char *what)
{
    print_message("  %-6s %-28s track %5.1f counts, overshoot %4.1f counts, settle %6.1f ms, "
                  "move %7.1f ms (ideal %7.1f), peak %6.1f deg/s\n",
                  B->name, what, r->track, r->overshoot, r->settle_ms, r->move_ms, r->ideal_ms,
                  r->peak_dps);
    note(r);
    if (r->track > TRACK_MAX_COUNTS)
        fail_msg("%s %s: tracking error %.1f counts > %.1f", B->name, what, r->track,
                 TRACK_MAX_COUNTS);
    if (r->overshoot > OVERSHOOT_MAX_COUNTS)
        fail_msg("%s %s: overshoot %.1f counts > %.1f", B->name, what, r->overshoot,
                 OVERSHOOT_MAX_COUNTS);
    if (r->settle_ms > SETTLE_MAX_MS)
        fail_msg("%s %s: settle %.1f ms > %.1f", B->name, what, r->settle_ms, SETTLE_MAX_MS);
    if (r->move_ms > r->ideal_ms + MOVE_SLACK_MS)
        fail_msg("%s %s: the reference took %.1f ms, ideal %.1f ms", B->name, what, r->move_ms,
                 r->ideal_ms);
    if (present() != goal_units)
        fail_msg("%s %s: present position %d, goal %d", B->name, what, present(), goal_units);
    assert_int_equal(s.regs.mem[REG_MOVING], 0);
}

/* Goal write in position mode at speed with ramps acc/dec (registers 34/35). */
static void goal_move(int32_t goal, uint16_t speed, uint8_t acc, uint8_t dec, const char *what)
{
    w8(REG_ACCELERATION, acc);
    w8(REG_DECELERATION, dec);
    w16(REG_MOVING_SPEED, speed);
    w16(REG_GOAL_POSITION, (uint16_t)goal);
    assert_int_equal(regs_get(&s.regs, REG_GOAL_POSITION), goal);
    struct move_result r = follow_move(speed, acc * 10.0, dec * 10.0);
    check_move(&r, goal, what);
}

/* --- tests ------------------------------------------------------------------------------- */

/* Rule 1 (§0): after power-up nothing moves for seconds, the driver is off, and the goal
 * register equals the present position; the same after a reboot with stored settings. */
static void rule1_nothing_moves_at_power_up(void **state)
{
    (void)state;
    for (unsigned v = 0; v < BOARD_COUNT; v++) {
        power_up(board_all[v]);
        assert_false(hal.motor.enabled);
        assert_int_equal(regs_get(&s.regs, REG_GOAL_POSITION), regs_present_position(&s.regs));
        run_ms(3000);
        assert_true(hal.motor.travel == 0.0);
        assert_false(hal.motor.enabled);
        assert_int_equal(hal.motor.duty, 0);
        assert_int_equal(s.regs.mem[REG_MOVING], 0);
        assert_int_equal(regs_get(&s.regs, REG_GOAL_POSITION), regs_present_position(&s.regs));
    }
    /* A foot that moved, had START/END and limits stored, and is rebooted where it
     * stands: the goal it had is not chased again. */
    ready(&board_foot);
    goal_move(100, 90, 36, 36, "to 100");
    assert_int_equal(start_end(1), 0);
    goal_move(40, 90, 36, 36, "to 40");
    hal_host_reboot(&hal);
    servo_init(&s, &board_foot, &hal);
    double t0 = hal.motor.travel;
    run_ms(3000);
    assert_true(hal.motor.travel - t0 == 0.0);
    assert_false(hal.motor.enabled);
    assert_int_equal(regs_get(&s.regs, REG_GOAL_POSITION), regs_present_position(&s.regs));
}

/* §6.1 position moves on foot, arm, wrist, finger: tracking, overshoot, settle, exact end. */
static void position_moves_per_variant(void **state)
{
    (void)state;
    worst = (struct move_result){0};
    for (unsigned v = 0; v < BOARD_COUNT; v++) {
        if (board_all[v]->variant == VARIANT_BASE)
            continue; /* the base moves by a goal relative to where it is (§6.1) */
        ready(board_all[v]);
        goal_move(30, 180, 36, 36, "to 30 at 180/s");
        goal_move(120, 90, 36, 36, "+90 at 90/s, 360/s^2");
        goal_move(60, 180, 100, 50, "-60 at 180/s, 1000/500");
        goal_move(63, 360, 36, 36, "+3 triangle");
        goal_move(163, 720, 255, 255, "+100 at 720/s, 2550/s^2");
        goal_move(153, 6, 36, 36, "-10 at 6/s");
        goal_move(154, 30, 0, 0, "+1 at 30/s, no ramps");
        goal_move(20, 1000, 36, 100, "-134 at 1000/s");
    }
    print_message("position moves: worst tracking %.1f counts, overshoot %.1f counts, settle "
                  "%.1f ms\n",
                  worst.track, worst.overshoot, worst.settle_ms);
}

/* §6.1 a new goal, speed or ramp mid-move is re-planned with no velocity jump, and the
 * move still ends exactly on the last goal. */
static void replan_mid_move(void **state)
{
    (void)state;
    ready(&board_foot);
    w8(REG_ACCELERATION, 36);
    w8(REG_DECELERATION, 36);
    w16(REG_MOVING_SPEED, 180);
    w16(REG_GOAL_POSITION, 300);
    run_ms(800);
    /* premise: cruising at 180 deg/s, 100 ahead but nearer than the stopping distance
     * (180^2 / (2 * 360) = 45 degrees) */
    assert_true(abs(present_speed() - 180) <= 5);
    assert_true(present() > 100 - 45 && present() < 100);
    int32_t v0 = s.motion.plan.vel;
    w16(REG_GOAL_POSITION, 100); /* behind the stopping point: stop, come back */
    next_tick();
    int32_t dv = s.motion.plan.vel - v0;
    assert_true(dv <= s.motion.lim.dec + s.motion.lim.dec / 500 && -dv <= s.motion.lim.dec);
    int32_t far = present();
    for (int i = 0; i < 600; i++) {
        run_ms(1);
        if (present() > far)
            far = present();
    }
    assert_true(far > 100 + 30);    /* it went past 100 ... */
    assert_true(present_speed() < 0); /* ... and is coming back */
    w16(REG_MOVING_SPEED, 60); /* a lower cruise speed: brake to it */
    w8(REG_DECELERATION, 100);
    struct move_result r = follow_move(60, 360, 1000);
    check_move(&r, 100, "re-planned to 100");
}

/* §6.1 base: the goal is relative to the present angle, and the move stops on it; from
 * rest (goal and speed in one write) and from speed mode (the goal written while it
 * turns: it decelerates early enough to stop on it). */
static void base_relative_goal(void **state)
{
    (void)state;
    ready(&board_base);
    int32_t p0 = present();
    uint8_t d[4] = {90, 0, 90, 0}; /* goal +90, speed 90 */
    assert_int_equal(wr(REG_GOAL_POSITION, d, 4), 0);
    struct move_result r = follow_move(90, 360, 360);
    check_move(&r, p0 + 90, "+90 relative from rest");
    int16_t back = -45;
    d[0] = (uint8_t)(uint16_t)back;
    d[1] = (uint8_t)((uint16_t)back >> 8);
    assert_int_equal(wr(REG_GOAL_POSITION, d, 4), 0);
    r = follow_move(90, 360, 360);
    check_move(&r, p0 + 45, "-45 relative");
    /* Turning in speed mode at 180 deg/s, then a goal 200 ahead of where it is. */
    w16(REG_MOVING_SPEED, 180);
    run_ms(1500);
    assert_int_equal(s.motion.mode, MOTION_SPEED);
    int32_t here = present();
    w16(REG_GOAL_POSITION, 200);
    r = follow_move(180, 360, 360);
    check_move(&r, here + 200, "+200 while turning");
    /* The acceleration registers of the base are 21/22. */
    w8(REG_BASE_ACCELERATION, 100);
    w8(REG_BASE_DECELERATION, 50);
    here = present();
    d[0] = 60;
    d[2] = 200;
    d[1] = d[3] = 0;
    assert_int_equal(wr(REG_GOAL_POSITION, d, 4), 0);
    r = follow_move(200, 1000, 500);
    check_move(&r, here + 60, "+60 with 21/22 = 100/50");
}

/* Mean measured speed in deg/s over ms milliseconds, and its smallest 100 ms window. */
static double mean_speed(uint32_t ms, double *min_window)
{
    double start = shaft_deg(), w = start, minw = 1e9;
    for (uint32_t i = 1; i <= ms; i++) {
        run_ms(1);
        if (i % 100u == 0) {
            double sp = (shaft_deg() - w) * 10.0;
            if (fabs(sp) < minw)
                minw = fabs(sp);
            w = shaft_deg();
        }
    }
    if (min_window)
        *min_window = minw;
    return (shaft_deg() - start) * 1000.0 / ms;
}

/* §6.2 speed mode (foot with limits 0/0, and the base): ramps to the speed and holds it,
 * bit 15 turns negative, 6 deg/s is held without stalling, speed 0 coasts (drive 0,
 * driver off, in the tick it arrives). */
static void speed_mode_holds_the_speed_reverses_on_bit_15_and_coasts_at_0(void **state)
{
    (void)state;
    for (int b = 0; b < 2; b++) {
        ready(b ? &board_base : &board_foot);
        if (!b)
            w_limits(0, 0);
        assert_true(regs_speed_mode(&s.regs));
        uint8_t a = b ? REG_BASE_ACCELERATION : REG_ACCELERATION;
        assert_int_equal(s.regs.mem[a], 36);
        w16(REG_MOVING_SPEED, 180);
        run_ms(500 + 200); /* 180 deg/s at 360 deg/s^2: 0.5 s */
        double minw;
        double m = mean_speed(1000, &minw);
        print_message("  %s speed mode 180: mean %.2f deg/s, slowest 100 ms %.2f, register %d\n",
                      B->name, m, minw, present_speed());
        assert_true(fabs(m - 180.0) < 180.0 * 0.01);
        assert_true(abs(present_speed() - 180) <= 5);
        assert_int_equal(s.regs.mem[REG_MOVING], 1);
        /* bit 15: the negative direction, through zero on the ramps */
        w16(REG_MOVING_SPEED, 0x8000u | 90u);
        run_ms(1000);
        m = mean_speed(1000, &minw);
        print_message("  %s speed mode -90: mean %.2f deg/s, register %d\n", B->name, m,
                      present_speed());
        assert_true(fabs(m + 90.0) < 90.0 * 0.01);
        assert_true(abs(present_speed() + 90) <= 5);
        int32_t p = present();
        run_ms(500);
        assert_true(present() < p); /* the position counts down */
        /* 6 deg/s is held: no stall, no stick-slip stop */
        w16(REG_MOVING_SPEED, 6);
        run_ms(1500);
        m = mean_speed(3000, &minw);
        print_message("  %s speed mode 6: mean %.3f deg/s, slowest 100 ms window %.3f deg/s\n",
                      B->name, m, minw);
        assert_true(fabs(m - 6.0) < 0.3);
        assert_true(minw > 3.0);
        /* speed 0: coast at once */
        w16(REG_MOVING_SPEED, 360);
        run_ms(1500);
        w16(REG_MOVING_SPEED, 0);
        assert_int_equal(hal.motor.duty, 0);
        assert_false(hal.motor.enabled);
        next_tick();
        assert_int_equal(hal.motor.duty, 0);
        assert_false(hal.motor.enabled);
        assert_int_equal(s.motion.mode, MOTION_OFF);
        assert_true(fabs(omega_dps()) > 100.0); /* coasting, not braked */
        run_ms(2000);
        assert_true(fabs(omega_dps()) < 1e-6);
        assert_int_equal(s.regs.mem[REG_MOVING], 0);
        assert_false(hal.motor.enabled);
    }
}

/* §5.1 register 40: the turned angle is signed 16-bit and wraps; on the base it keeps
 * counting through +32767 -> -32768 while the wheel turns, and a relative goal there
 * still lands exactly. */
static void turned_angle_wraps(void **state)
{
    (void)state;
    ready(&board_base);
    w16(REG_MOVING_SPEED, 1000);
    int32_t prev = present();
    int wraps = 0;
    for (int i = 0; i < 36000; i++) {
        run_ms(1);
        int32_t now = present();
        int32_t d = (int32_t)(int16_t)(uint16_t)(now - prev); /* step modulo 2^16 */
        if (d < 0 || d > 3)
            fail_msg("turned angle stepped from %d to %d", prev, now);
        if (now < prev)
            wraps++;
        prev = now;
    }
    assert_int_equal(wraps, 1);
    double deg = (double)(s.motion.ctl.counts - s.motion.zero) / COUNTS_PER_DEG;
    assert_true(abs((int16_t)(uint16_t)(int32_t)lround(deg) - present()) <= 1);
    /* a relative goal across the wrap: stops on (angle + 500) modulo 2^16 */
    int32_t here = present();
    w16(REG_GOAL_POSITION, 500);
    struct move_result r = follow_move(1000, 360, 360);
    (void)r;
    assert_int_equal(present(), (int16_t)(uint16_t)(here + 500));
    assert_int_equal(s.regs.mem[REG_MOVING], 0);
}

/* §0 rule 3 and §6.3: the brake stops whatever runs and holds; releasing it, or waking
 * from sleep, starts nothing. Waits until the shaft has stopped (STOP_MS) and checks it
 * holds still (HOLD_COUNTS) and nothing turns after the release. */
#define STOP_MS 300u
#define HOLD_COUNTS 2.0
#define RELEASE_TRAVEL_COUNTS 1.0

/* Brake on, then off; returns 0 if all held, else what went wrong (static buffer). */
static const char *brake_then_release_why(const char *from)
{
    static char why[200];
    w8(REG_BRAKE, 1);
    /* within one control tick: the reference is at rest, held with torque */
    next_tick();
    if (s.motion.plan.vel != 0 || s.motion.mode != MOTION_HOLD || !hal.motor.enabled) {
        snprintf(why, sizeof why,
                 "%s: brake from %s: one tick later reference vel %d, mode %u, driver %d", B->name,
                 from, s.motion.plan.vel, s.motion.mode, hal.motor.enabled);
        w8(REG_BRAKE, 0);
        return why;
    }
    run_ms(STOP_MS);
    if (fabs(omega_dps()) > 2.0) {
        snprintf(why, sizeof why, "%s: brake from %s: still turning at %.1f deg/s after %u ms",
                 B->name, from, omega_dps(), STOP_MS);
        w8(REG_BRAKE, 0);
        return why;
    }
    int64_t c = s.motion.ctl.counts;
    double t = travel_counts();
    run_ms(500);
    if (llabs(s.motion.ctl.counts - c) > HOLD_COUNTS || travel_counts() - t > 2 * HOLD_COUNTS) {
        snprintf(why, sizeof why, "%s: brake from %s: does not hold (moved %lld counts)", B->name,
                 from, (long long)(s.motion.ctl.counts - c));
        w8(REG_BRAKE, 0);
        return why;
    }
    w8(REG_BRAKE, 0);
    t = travel_counts();
    run_ms(1500);
    if (travel_counts() - t > RELEASE_TRAVEL_COUNTS || s.regs.mem[REG_MOVING]) {
        snprintf(why, sizeof why, "%s: releasing the brake (after %s) moved %.1f counts", B->name,
                 from, travel_counts() - t);
        return why;
    }
    return 0;
}

static void brake_then_release(const char *from)
{
    /* premise: something runs and the shaft turns */
    if (!s.regs.mem[REG_MOVING] || fabs(omega_dps()) < 20.0)
        fail_msg("%s: before the brake from %s: moving %u, shaft at %.1f deg/s", B->name, from,
                 s.regs.mem[REG_MOVING], omega_dps());
    const char *why = brake_then_release_why(from);
    if (why)
        fail_msg("%s", why);
}

static void sleep_then_wake(void)
{
    double before_dps = omega_dps();
    w8(REG_SLEEP, 1);
    assert_false(hal.motor.enabled);
    assert_int_equal(hal.motor.duty, 0);
    run_ms(2000); /* coasts to rest */
    if (fabs(omega_dps()) > 1e-6)
        fail_msg("%s: asleep 2 s after %.1f deg/s, still turning at %.3f deg/s", B->name,
                 before_dps, omega_dps());
    w8(REG_SLEEP, 0);
    double t = travel_counts();
    run_ms(1500);
    if (travel_counts() - t > RELEASE_TRAVEL_COUNTS || hal.motor.enabled)
        fail_msg("%s: waking moved %.1f counts (driver %d)", B->name, travel_counts() - t,
                 hal.motor.enabled);
}

/* --- random command sequences ---------------------------------------------------------- */
static uint16_t lo_lim, hi_lim;

static uint16_t rnd_goal(void)
{
    return (uint16_t)(lo_lim + rnd((uint32_t)(hi_lim - lo_lim + 1u)));
}

static uint16_t rnd_speed(void)
{
    static const uint16_t sp[] = {6, 20, 45, 90, 180, 360, 720, 1000};
    return sp[rnd(8)];
}

/* Writes that may be refused (e.g. a goal after an aborted homing left no reference). */
static void try8(uint8_t addr, uint8_t v)
{
    (void)wr(addr, &v, 1);
}

static void try16(uint8_t addr, uint16_t v)
{
    uint8_t d[2] = {(uint8_t)v, (uint8_t)(v >> 8)};
    (void)wr(addr, d, 2);
}

static void rnd_position_mode(void)
{
    if (B->variant != VARIANT_BASE && regs_speed_mode(&s.regs)) {
        uint8_t d[4] = {(uint8_t)lo_lim, (uint8_t)(lo_lim >> 8), (uint8_t)hi_lim,
                        (uint8_t)(hi_lim >> 8)};
        (void)wr(REG_CW_LIMIT, d, 4);
    }
}

/* One random command; returns its name. Commands may be refused (braked, asleep, no
 * homing reference): that is part of the sequence. */
static const char *random_command(void)
{
    uint8_t acc_reg = B->variant == VARIANT_BASE ? REG_BASE_ACCELERATION : REG_ACCELERATION;
    switch (rnd(13)) {
    case 0:
    case 1: /* goal move (base: relative) */
        rnd_position_mode();
        try8(acc_reg, (uint8_t)(1 + rnd(255)));
        try16(REG_MOVING_SPEED, rnd_speed());
        if (B->variant == VARIANT_BASE)
            try16(REG_GOAL_POSITION, (uint16_t)(int16_t)((int)rnd(721) - 360));
        else
            try16(REG_GOAL_POSITION, rnd_goal());
        return "goal";
    case 2: /* re-plan: a new goal only */
        try16(REG_GOAL_POSITION, B->variant == VARIANT_BASE ? (uint16_t)rnd(90) : rnd_goal());
        return "new goal";
    case 3: /* new speed (in speed mode: starts/changes it) */
        try16(REG_MOVING_SPEED, (uint16_t)(rnd_speed() | (rnd(2) ? 0x8000u : 0u)));
        return "speed";
    case 4: /* speed mode */
        if (B->variant != VARIANT_BASE) {
            uint8_t z[4] = {0, 0, 0, 0};
            (void)wr(REG_CW_LIMIT, z, 4);
        }
        try16(REG_MOVING_SPEED, (uint16_t)(rnd_speed() | (rnd(2) ? 0x8000u : 0u)));
        return "speed mode";
    case 5: { /* trajectory */
        rnd_position_mode();
        uint16_t a[10], v[10];
        uint8_t n = (uint8_t)(2 + rnd(9));
        for (uint8_t i = 0; i < n; i++) {
            a[i] = rnd_goal();
            v[i] = (uint16_t)(10 + rnd(240));
        }
        traj_write_pts(a, v, n, (int)rnd(2));
        traj_action();
        return "trajectory";
    }
    case 6: /* custom move relative */
        rnd_position_mode();
        custom_rel((uint16_t)rnd(120), (uint16_t)(rnd_speed() | (rnd(2) ? 0x8000u : 0u)),
                   (int)rnd(2), (uint8_t)(1 + rnd(255)), (uint8_t)(1 + rnd(255)));
        return "custom relative";
    case 7: /* custom move absolute */
        rnd_position_mode();
        custom_abs(rnd_goal(), rnd_speed(), (uint8_t)(1 + rnd(255)), (uint8_t)(1 + rnd(255)));
        return "custom absolute";
    case 8: /* new ramps mid-motion */
        try8((uint8_t)(acc_reg + 1u), (uint8_t)rnd(256));
        return "ramps";
    case 9: /* brake pulse */
        try8(REG_BRAKE, 1);
        run_ms(rnd(100));
        try8(REG_BRAKE, 0);
        return "brake pulse";
    case 10: /* sleep pulse */
        try8(REG_SLEEP, 1);
        run_ms(rnd(100));
        try8(REG_SLEEP, 0);
        return "sleep pulse";
    case 11: /* homing (§9; on boards without switches it fails at once) */
        rnd_position_mode();
        try8(REG_HOMING, 1);
        return "homing";
    default: /* speed 0 */
        try16(REG_MOVING_SPEED, 0);
        return "speed 0";
    }
}

/* Rule 3 property: random command sequences on every variant, then speed 0 (drive 0 and
 * driver off within one control tick, and it stays so) or the brake (reference at rest
 * within one tick, the shaft stops and holds, releasing starts nothing), or sleep then
 * wake (nothing starts). */
static void speed_0_or_brake_stops_within_a_tick_after_any_commands(void **state)
{
    (void)state;
    rng = 0x3u;
    unsigned runs = 0, by_speed0 = 0, by_brake = 0, by_sleep = 0;
    unsigned brake_from[3] = {0, 0, 0}, brake_fail[3] = {0, 0, 0};
    static char first_fail[3][200];
    for (unsigned iter = 0; iter < 500; iter++) {
        ready(board_all[iter % BOARD_COUNT]);
        lo_lim = B->variant == VARIANT_BASE ? 0 : 10;
        hi_lim = wh() ? (B->variant == VARIANT_WRIST ? 260 : 170) : 350;
        unsigned n = 1 + rnd(6);
        const char *last = "";
        for (unsigned i = 0; i < n; i++) {
            last = random_command();
            run_ms(rnd(400));
        }
        switch (rnd(3)) {
        case 0: {
            w16(REG_MOVING_SPEED, 0);
            if (hal.motor.duty != 0 || hal.motor.enabled)
                fail_msg("%s after %s: speed 0 left drive %d, driver %d", B->name, last,
                         hal.motor.duty, hal.motor.enabled);
            next_tick();
            for (int t = 0; t < 500; t++) {
                if (hal.motor.duty != 0 || hal.motor.enabled || s.motion.mode != MOTION_OFF)
                    fail_msg("%s after %s: %d ms after speed 0: drive %d, driver %d", B->name,
                             last, t, hal.motor.duty, hal.motor.enabled);
                run_ms(1);
            }
            by_speed0++;
            break;
        }
        case 1: {
            if (s.safety.latched) {
                /* A protection unload is latched (the finger's 1 A limit trips under some
                 * random sequences): torque stays off, the brake cannot override it. */
                w8(REG_BRAKE, 1);
                next_tick();
                if (hal.motor.enabled || hal.motor.duty)
                    fail_msg("%s: the brake drove a motor whose unload is latched", B->name);
                w8(REG_BRAKE, 0);
                by_brake++;
                break;
            }
            char from[80];
            /* 0: driver on (running or holding), 1: driver off and still turning
             * (coasting after speed 0 or sleep), 2: driver off at rest */
            int kind = s.motion.mode != MOTION_OFF ? 0 : fabs(omega_dps()) > 1.0 ? 1 : 2;
            static const char *const kinds[] = {"", " (coasting)", " (driver off, at rest)"};
            snprintf(from, sizeof from, "a sequence ending in %s%s", last, kinds[kind]);
            const char *why = brake_then_release_why(from);
            if (why && !brake_fail[kind]++)
                snprintf(first_fail[kind], sizeof first_fail[kind], "%s", why);
            brake_from[kind]++;
            by_brake++;
            break;
        }
        default:
            sleep_then_wake();
            by_sleep++;
            break;
        }
        runs++;
    }
    print_message("rule 3: %u random sequences: %u ended by speed 0, %u by the brake, %u by "
                  "sleep\n",
                  runs, by_speed0, by_brake, by_sleep);
    print_message("rule 3: brake with the driver on: %u/%u failed; while coasting (after speed "
                  "0 or sleep): %u/%u failed; driver off at rest: %u/%u failed\n",
                  brake_fail[0], brake_from[0], brake_fail[1], brake_from[1], brake_fail[2],
                  brake_from[2]);
    for (int i = 0; i < 3; i++)
        if (brake_fail[i])
            print_message("rule 3: first failure: %s\n", first_fail[i]);
    for (int i = 0; i < 3; i++) {
        assert_int_equal(brake_fail[i], 0);
        assert_true(brake_from[i] > 0); /* premise: every kind of start was tried */
    }
    assert_true(by_speed0 > 0 && by_sleep > 0);
}

/* Rule 3, explicitly for each kind of motion: a move, speed mode, a trajectory, a custom
 * move, and a motor coasting after speed 0 (§6.3: brake on = stop at once and hold). */
static void brake_stops_every_motion(void **state)
{
    (void)state;
    ready(&board_foot);
    w16(REG_MOVING_SPEED, 360);
    w16(REG_GOAL_POSITION, 300);
    run_ms(300);
    brake_then_release("a move");

    ready(&board_foot);
    w_limits(0, 0);
    w16(REG_MOVING_SPEED, 720);
    run_ms(1500);
    brake_then_release("speed mode at 720 deg/s");

    ready(&board_arm);
    const uint16_t a[] = {100, 300, 50}, v[] = {200, 200, 200};
    assert_int_equal(traj_write_pts(a, v, 3, 1), 0);
    assert_int_equal(traj_action(), 0);
    run_ms(700);
    brake_then_release("a trajectory");

    ready(&board_wrist);
    assert_int_equal(custom_rel(100, 0x8000u | 300u, 0, 0, 0), 0);
    run_ms(200);
    brake_then_release("a custom move");

}

/* §6.3 "brake on: stop at once and hold" and rule 3 "whatever the motor is doing": a
 * motor coasting after speed 0 (§6.2, torque off) is stopped and held by the brake. */
static void brake_stops_a_coasting_motor(void **state)
{
    (void)state;
    ready(&board_base);
    w16(REG_MOVING_SPEED, 720);
    run_ms(2500);
    w16(REG_MOVING_SPEED, 0); /* coasting now */
    run_ms(5);
    double coast_dps = omega_dps();
    print_message("  brake while coasting at %.0f deg/s\n", coast_dps);
    /* premise: coasting (driver off, no drive, no motion running), still fast */
    assert_false(hal.motor.enabled);
    assert_int_equal(hal.motor.duty, 0);
    assert_int_equal(s.motion.mode, MOTION_OFF);
    assert_true(coast_dps > 500.0);
    const char *why = brake_then_release_why("coasting after speed 0");
    if (why)
        fail_msg("%s", why);
}

/* §6.3: sleep is torque off; waking starts nothing, even with a move pending. */
static void sleep_and_wake(void **state)
{
    (void)state;
    ready(&board_foot);
    w16(REG_MOVING_SPEED, 90);
    w16(REG_GOAL_POSITION, 300);
    run_ms(500);
    assert_true(omega_dps() > 60.0); /* premise: asleep in the middle of the move */
    sleep_then_wake();
    /* a goal written while asleep is stored only; waking does not chase it */
    w8(REG_SLEEP, 1);
    w16(REG_GOAL_POSITION, 10);
    run_ms(1000);
    sleep_then_wake();
    /* the next motion command works */
    w16(REG_GOAL_POSITION, 50);
    struct move_result r = follow_move(90, 360, 360);
    check_move(&r, 50, "after waking");
}

/* §4.6 START/END: 1 makes the present position 0 and the CW limit 0; 2 makes the CCW
 * limit the present position; both survive a reboot. Other values, speed mode and the
 * base are instruction errors. */
static void start_end_semantics(void **state)
{
    (void)state;
    ready(&board_foot);
    goal_move(100, 180, 36, 36, "to 100");
    w_limits(20, 360);
    assert_int_equal(start_end(1), 0);
    next_tick();
    assert_int_equal(present(), 0);
    assert_int_equal(regs_get(&s.regs, REG_CW_LIMIT), 0);
    assert_int_equal(regs_get(&s.regs, REG_CCW_LIMIT), 360);
    assert_true(fabs(shaft_deg() - 100.0) < 0.1); /* nothing moved */
    goal_move(70, 180, 36, 36, "to 70 from the new zero");
    assert_true(fabs(shaft_deg() - 170.0) < 0.1);
    assert_int_equal(start_end(2), 0);
    assert_int_equal(regs_get(&s.regs, REG_CCW_LIMIT), 70);
    assert_int_equal(regs_get(&s.regs, REG_CW_LIMIT), 0);
    /* goals are clamped to the new range */
    goal_move(50, 180, 36, 36, "to 50");
    w16(REG_GOAL_POSITION, 200);
    assert_int_equal(regs_get(&s.regs, REG_GOAL_POSITION), 70);
    struct move_result r = follow_move(180, 360, 360);
    check_move(&r, 70, "clamped to 70");
    /* invalid */
    assert_int_equal(start_end(0), ERR_INSTRUCTION);
    assert_int_equal(start_end(3), ERR_INSTRUCTION);
    assert_int_equal(cmd(INS_START_END, NULL, 0), ERR_INSTRUCTION);
    const uint8_t two[] = {1, 1};
    assert_int_equal(cmd(INS_START_END, two, 2), ERR_INSTRUCTION);
    /* stored: a reboot keeps both limits */
    run_ms(100);
    hal_host_reboot(&hal);
    servo_init(&s, &board_foot, &hal);
    assert_int_equal(regs_get(&s.regs, REG_CW_LIMIT), 0);
    assert_int_equal(regs_get(&s.regs, REG_CCW_LIMIT), 70);
    run_ms(1000);
    assert_false(hal.motor.enabled);
    /* speed mode: refused, nothing changes */
    quiet_setup();
    w_limits(0, 0);
    assert_int_equal(start_end(1), ERR_INSTRUCTION);
    assert_int_equal(start_end(2), ERR_INSTRUCTION);
    assert_int_equal(regs_get(&s.regs, REG_CCW_LIMIT), 0);
    ready(&board_base);
    assert_int_equal(start_end(1), ERR_INSTRUCTION);
    assert_int_equal(start_end(2), ERR_INSTRUCTION);
}

/* Q24 of an acceleration register, as src/motion.c's accel_q24 (10 deg/s^2 units). */
static int32_t acc_q24(uint8_t reg)
{
    return (int32_t)(((int64_t)reg * 10 * 16384 << PLANNER_SHIFT) / (360LL * 1000 * 1000));
}

/* §4.8 CUSTOM MOVE: relative both directions (4 and 6 parameters), absolute; acc/dec are
 * written into 34/35 (base 21/22) and used. */
static void custom_move_goes_either_way_with_its_own_ramps(void **state)
{
    (void)state;
    ready(&board_arm);
    goal_move(100, 180, 36, 36, "to 100");
    /* relative +40, 4 parameters: the ramps in the registers */
    assert_int_equal(custom_rel(40, 120, 0, 0, 0), 0);
    assert_int_equal(s.motion.lim.acc, acc_q24(36));
    struct move_result r = follow_move(120, 360, 360);
    check_move(&r, 140, "custom relative +40");
    /* relative -70, bit 15, with acc 200 / dec 20 written into 34/35 */
    assert_int_equal(custom_rel(70, 0x8000u | 150u, 1, 200, 20), 0);
    assert_int_equal(s.regs.mem[REG_ACCELERATION], 200);
    assert_int_equal(s.regs.mem[REG_DECELERATION], 20);
    assert_int_equal(s.motion.lim.acc, acc_q24(200));
    assert_int_equal(s.motion.lim.dec, acc_q24(20));
    r = follow_move(150, 2000, 200);
    check_move(&r, 70, "custom relative -70");
    /* absolute to 250 */
    assert_int_equal(custom_abs(250, 300, 100, 100), 0);
    assert_int_equal(s.regs.mem[REG_ACCELERATION], 100);
    assert_int_equal(s.regs.mem[REG_DECELERATION], 100);
    r = follow_move(300, 1000, 1000);
    check_move(&r, 250, "custom absolute 250");
    /* absolute: the speed is a magnitude only (bit 15 ignored) */
    assert_int_equal(custom_abs(200, 0x8000u | 90u, 36, 36), 0);
    r = follow_move(90, 360, 360);
    check_move(&r, 200, "custom absolute, bit 15 set");
    /* absolute beyond the limit: clamped */
    assert_int_equal(custom_abs(1000, 300, 100, 100), 0);
    r = follow_move(300, 1000, 1000);
    check_move(&r, 420, "custom absolute clamped to 420");
    /* malformed: sub 1 with 6 parameters... (5 or 7 bytes only), sub 2 with 4, sub 3 */
    const uint8_t bad1[] = {1, 10, 0, 10, 0, 5};
    const uint8_t bad2[] = {2, 10, 0, 10, 0};
    const uint8_t bad3[] = {3, 10, 0, 10, 0, 5, 5};
    assert_int_equal(cmd(INS_CUSTOM, bad1, sizeof bad1), ERR_INSTRUCTION);
    assert_int_equal(cmd(INS_CUSTOM, bad2, sizeof bad2), ERR_INSTRUCTION);
    assert_int_equal(cmd(INS_CUSTOM, bad3, sizeof bad3), ERR_INSTRUCTION);
    assert_int_equal(s.motion.mode, MOTION_HOLD);
    /* the base: relative, ramps into 21/22 */
    ready(&board_base);
    int32_t p0 = present();
    assert_int_equal(custom_rel(90, 0x8000u | 180u, 1, 50, 70), 0);
    assert_int_equal(s.regs.mem[REG_BASE_ACCELERATION], 50);
    assert_int_equal(s.regs.mem[REG_BASE_DECELERATION], 70);
    assert_int_equal(s.regs.mem[REG_ACCELERATION], 0); /* not applicable on the base */
    r = follow_move(180, 500, 700);
    check_move(&r, p0 - 90, "base custom relative -90");
    assert_int_equal(custom_rel(30, 60, 0, 0, 0), 0);
    r = follow_move(60, 500, 700);
    check_move(&r, p0 - 60, "base custom relative +30");
}

/* Run a trajectory to its end, recording for each point the lowest present speed
 * (register 38, deg/s) while the shaft is within 0.5 degree of it, and whether it came to
 * rest on it (within OVERSHOOT_MAX_COUNTS). */
static void run_trajectory(const uint16_t *a, uint8_t n, double *min_at, bool *stopped_at)
{
    for (uint8_t i = 0; i < n; i++) {
        min_at[i] = 1e9;
        stopped_at[i] = false;
    }
    for (int t = 0; t < 30000 && s.motion.mode == MOTION_TRAJ; t++) {
        next_tick();
        double here = (double)(s.motion.ctl.counts - s.motion.zero) / COUNTS_PER_DEG;
        double sp = fabs((double)present_speed()); /* register 38, deg/s at resolution 10 */
        for (uint8_t i = 0; i < n; i++) {
            if (fabs(here - a[i]) < 0.5 && sp < min_at[i])
                min_at[i] = sp;
            if (fabs(here - a[i]) <= OVERSHOOT_MAX_COUNTS / COUNTS_PER_DEG &&
                fabs(omega_dps()) < 1.0)
                stopped_at[i] = true; /* the shaft itself at rest on the point (a move's */
                                      /* overshoot bound: it reverses there at once)   */
        }
    }
    assert_int_equal(s.motion.mode, MOTION_HOLD);
    run_ms(400);
}

/* Points first..last of a one-direction run from start at speed v with ramps acc/dec
 * (deg/s^2) are passed at no less than 60 % of the ideal trapezoid's speed there (the
 * cruise speed, or less while accelerating from start or braking for end), never at
 * rest. */
static void check_pass_through(const uint16_t *a, int first, int last, double start, double end,
                               double v, double acc, double dec, const double *min_at,
                               const bool *stopped, const char *what)
{
    double lowest = 1e9;
    for (int i = first; i <= last; i++) {
        double ideal = v;
        double up = sqrt(2 * acc * fabs(a[i] - start)), down = sqrt(2 * dec * fabs(end - a[i]));
        if (up < ideal)
            ideal = up;
        if (down < ideal)
            ideal = down;
        if (min_at[i] / ideal < lowest)
            lowest = min_at[i] / ideal;
        if (stopped[i] || min_at[i] < 0.6 * ideal)
            fail_msg("%s: passing intermediate point %d (%u) at %.1f deg/s, ideal %.1f%s", what, i,
                     a[i], min_at[i], ideal, stopped[i] ? ", stopped there" : "");
    }
    print_message("  %s: intermediate points passed at >= %.0f %% of the ideal profile's speed\n",
                  what, lowest * 100);
}

/* §4.7: TRAJECTORY WRITE replaces, both encodings, >= 63 points; ACTION runs the points,
 * passing intermediate ones without stopping where the direction does not change,
 * stopping at reversals and at the end, ending on the last point; it can run again. */
static void trajectory_passes_points_stops_at_reversals_and_ends_on_the_last(void **state)
{
    (void)state;
    double min_at[84];
    bool stopped[84];
    ready(&board_foot);
    goal_move(0 + 10, 180, 36, 36, "to 10");

    /* monotonic, 4-byte form: through 40, 70, 100 without stopping, ends on 130 */
    const uint16_t a1[] = {40, 70, 100, 130}, v1[] = {90, 90, 90, 90};
    assert_int_equal(traj_write_pts(a1, v1, 4, 1), 0);
    assert_int_equal(s.traj.count, 4);
    assert_int_equal(traj_action(), 0);
    run_trajectory(a1, 4, min_at, stopped);
    check_pass_through(a1, 0, 2, 10, 130, 90, 360, 360, min_at, stopped, "4 points up");
    assert_int_equal(present(), 130);

    /* reversals, 3-byte form: 160 (stop), 100 (stop), 150 (end) */
    const uint16_t a2[] = {160, 100, 150}, v2[] = {120, 120, 120};
    assert_int_equal(traj_write_pts(a2, v2, 3, 0), 0);
    assert_int_equal(s.traj.count, 3);
    assert_int_equal(s.traj.pt[1].speed, 120);
    assert_int_equal(traj_action(), 0);
    run_trajectory(a2, 3, min_at, stopped);
    assert_true(stopped[0] && stopped[1]);
    assert_int_equal(present(), 150);

    /* replace: a 5-point trajectory, then a 2-point one; ACTION runs the 2 points */
    const uint16_t a3[] = {300, 310, 320, 330, 340}, v3[] = {50, 50, 50, 50, 50};
    assert_int_equal(traj_write_pts(a3, v3, 5, 1), 0);
    const uint16_t a4[] = {120, 90}, v4[] = {100, 100};
    assert_int_equal(traj_write_pts(a4, v4, 2, 0), 0);
    assert_int_equal(s.traj.count, 2);
    assert_int_equal(traj_action(), 0);
    run_trajectory(a4, 2, min_at, stopped);
    assert_int_equal(present(), 90);
    assert_true(shaft_deg() < 200.0);
    /* the points remain: run again from 90: up to 120 (a reversal: it stops there), back to 90 */
    assert_int_equal(traj_action(), 0);
    run_trajectory(a4, 2, min_at, stopped);
    assert_true(stopped[0]);
    assert_int_equal(present(), 90);

    /* count 0 clears; ACTION on an empty store is an instruction error */
    const uint8_t zero = 0;
    assert_int_equal(cmd(INS_TRAJ_WRITE, &zero, 1), 0);
    assert_int_equal(s.traj.count, 0);
    assert_int_equal(traj_action(), ERR_INSTRUCTION);
    /* speed 0 in a point, a bad size: refused, store unchanged */
    assert_int_equal(traj_write_pts(a4, v4, 2, 0), 0);
    const uint16_t vz[] = {100, 0};
    assert_int_equal(traj_write_pts(a4, vz, 2, 1), ERR_INSTRUCTION);
    assert_int_equal(s.traj.count, 2);
    const uint8_t odd[] = {2, 10, 0, 5, 20, 0};
    assert_int_equal(cmd(INS_TRAJ_WRITE, odd, sizeof odd), ERR_INSTRUCTION);
    const uint8_t with_param = 1;
    assert_int_equal(cmd(INS_TRAJ_ACTION, &with_param, 1), ERR_INSTRUCTION);

    /* 63 points in the 4-byte form (LEN 255), monotonic: no stop until the last */
    uint16_t a5[84], v5[84];
    for (int i = 0; i < 63; i++) {
        a5[i] = (uint16_t)(92 + 4 * i);
        v5[i] = 200;
    }
    assert_int_equal(traj_write_pts(a5, v5, 63, 1), 0);
    assert_int_equal(s.traj.count, 63);
    assert_int_equal(traj_action(), 0);
    run_trajectory(a5, 63, min_at, stopped);
    check_pass_through(a5, 0, 61, 90, 92 + 4 * 62, 200, 360, 360, min_at, stopped,
                       "63 points, 4-byte form");
    assert_int_equal(present(), 92 + 4 * 62);
    /* 84 points in the 3-byte form, going down by 3 */
    for (int i = 0; i < 84; i++) {
        a5[i] = (uint16_t)(340 - 3 * i);
        v5[i] = 250;
    }
    assert_int_equal(traj_write_pts(a5, v5, 84, 0), 0);
    assert_int_equal(s.traj.count, 84);
    assert_int_equal(traj_action(), 0);
    run_trajectory(a5, 84, min_at, stopped);
    check_pass_through(a5, 1, 82, 92 + 4 * 62, 340 - 3 * 83, 250, 360, 360, min_at, stopped,
                       "84 points, 3-byte form");
    assert_int_equal(present(), 340 - 3 * 83);
    /* a point speed above vmax and per-point speeds: a slow point in the middle of a
     * monotonic run is passed at (about) its own speed, never stopped at */
    const uint16_t a6[] = {100, 150, 200}, v6[] = {300, 60, 300};
    assert_int_equal(traj_write_pts(a6, v6, 3, 1), 0);
    assert_int_equal(traj_action(), 0);
    run_trajectory(a6, 3, min_at, stopped);
    print_message("  per-point speeds 300/60/300: passing 100 at %.1f, 150 at %.1f deg/s\n",
                  min_at[0], min_at[1]);
    assert_false(stopped[0] || stopped[1]);
    assert_true(min_at[1] > 0.8 * 60.0 && min_at[1] < 1.2 * 60.0); /* about its own speed */
    assert_int_equal(present(), 200);
}

/* §5: a resolution change (register 13) stops any motion (and drops the trajectory);
 * positions are reported in the new unit. */
static void resolution_change_stops(void **state)
{
    (void)state;
    ready(&board_foot);
    w16(REG_MOVING_SPEED, 180);
    w16(REG_GOAL_POSITION, 300);
    run_ms(500);
    w8(REG_RESOLUTION, 5); /* 0.5 degree per unit */
    next_tick();
    assert_int_equal(s.motion.plan.vel, 0);
    assert_int_equal(s.motion.mode, MOTION_HOLD);
    run_ms(STOP_MS);
    double t = travel_counts();
    int64_t c = s.motion.ctl.counts;
    run_ms(1000);
    assert_true(travel_counts() - t < 2 * HOLD_COUNTS);
    assert_true(llabs(s.motion.ctl.counts - c) <= HOLD_COUNTS);
    /* present position in half degrees now */
    double deg = (double)(s.motion.ctl.counts - s.motion.zero) / COUNTS_PER_DEG;
    assert_true(abs(present() - (int32_t)lround(deg * 2)) <= 1);
    assert_int_equal(s.regs.mem[REG_MOVING], 0);

    /* a trajectory: stopped and dropped */
    ready(&board_foot);
    const uint16_t a[] = {100, 300}, v[] = {200, 200};
    assert_int_equal(traj_write_pts(a, v, 2, 1), 0);
    assert_int_equal(traj_action(), 0);
    run_ms(400);
    w8(REG_RESOLUTION, 20);
    next_tick();
    assert_int_equal(s.motion.plan.vel, 0);
    assert_int_equal(s.motion.mode, MOTION_HOLD);
    assert_int_equal(s.traj.count, 0);
    assert_int_equal(traj_action(), ERR_INSTRUCTION);
    run_ms(STOP_MS);
    t = travel_counts();
    run_ms(1000);
    assert_true(travel_counts() - t < 2 * HOLD_COUNTS);

    /* speed mode: stopped too; then a move in the new unit lands on it */
    ready(&board_foot);
    w_limits(0, 0);
    w16(REG_MOVING_SPEED, 180);
    run_ms(800);
    w8(REG_RESOLUTION, 1); /* 0.1 degree */
    next_tick();
    assert_int_equal(s.motion.plan.vel, 0);
    assert_int_equal(s.motion.mode, MOTION_HOLD);
    run_ms(STOP_MS + 500);
    /* speed mode at resolution 1: 900 units/s is 90 deg/s, reported as 900 */
    w_limits(0, 0);
    w16(REG_MOVING_SPEED, 900);
    run_ms(700);
    double m = mean_speed(1000, NULL);
    print_message("  resolution 1, speed 900: mean %.2f deg/s, register %d\n", m, present_speed());
    assert_true(fabs(m - 90.0) < 1.0);
    assert_true(abs(present_speed() - 900) <= 20);
    w8(REG_BRAKE, 1);
    run_ms(STOP_MS);
    w8(REG_BRAKE, 0);
    w_limits(0, 3600);
    int32_t here = present();
    int32_t goal = here + 55 > 3600 ? here - 55 : here + 55; /* 5.5 degrees */
    w16(REG_MOVING_SPEED, 300); /* 30 deg/s */
    w16(REG_GOAL_POSITION, (uint16_t)goal);
    struct move_result r = follow_move(30, 360, 360);
    check_move(&r, goal, "5.5 deg at resolution 1");
}

/* §6.1 "without a jump in velocity" from any state: a motion command that finds the
 * motor coasting (after speed 0) takes it up at the speed it has (within the lag of the
 * measured-speed filter), in either direction. Kept last: the negative direction runs
 * engage() in src/motion.c with a negative measured speed, which UBSan reports (and
 * aborts on) when the core itself is built with the sanitizers. */
/* A load's weight on the arm (the plant's gravity term): a move lands and the arm holds
 * against the weight with no standing error (integral action at rest), and a sag when
 * the drive is off is the weight, not the firmware. */
static void holds_against_gravity(void **state)
{
    (void)state;
    ready(&board_arm);
    hal.motor.p.gravity = 0.05; /* N m at the output: a quarter of the holding torque */
    w16(REG_MOVING_SPEED, 90);
    w16(REG_GOAL_POSITION, 180);
    run_ms(4000);
    int64_t goal = (int64_t)180 * 16384 / 360 + s.motion.zero;
    if (llabs(s.motion.ctl.counts - goal) > 2)
        fail_msg("arm under load rests %lld counts from the goal",
                 (long long)(s.motion.ctl.counts - goal));
    int64_t c = s.motion.ctl.counts;
    run_ms(2000);
    assert_true(llabs(s.motion.ctl.counts - c) <= 1);
    assert_int_equal(s.regs.mem[REG_MOVING], 0);
    assert_int_equal(regs_get(&s.regs, REG_TURNED_ANGLE), 180);
    /* premise: the weight is real: with the drive off (sleep) the arm sags */
    double t = travel_counts();
    w8(REG_SLEEP, 1);
    run_ms(300);
    assert_true(travel_counts() - t > 45.0);
    hal.motor.p.gravity = 0.0;
}

static void reengage_while_coasting(void **state)
{
    (void)state;
    const double q24_per_dps = 16384.0 / 360.0 / 1000.0 * (double)PLANNER_ONE;
    for (int neg = 0; neg < 2; neg++) {
        ready(&board_foot);
        w_limits(0, 0);
        uint16_t dir = neg ? 0x8000u : 0u;
        w16(REG_MOVING_SPEED, (uint16_t)(dir | 360u));
        run_ms(1500);
        w16(REG_MOVING_SPEED, 0); /* coast */
        run_ms(20);
        double coasting = omega_dps();
        assert_true(fabs(coasting) > 200.0);
        w16(REG_MOVING_SPEED, (uint16_t)(dir | 360u)); /* speed mode again, from here */
        double ref_dps = s.motion.plan.vel / q24_per_dps;
        print_message("  re-engaged while coasting at %.1f deg/s: reference starts at %.1f\n",
                      coasting, ref_dps);
        assert_true(fabs(ref_dps - coasting) < 0.25 * fabs(coasting)); /* the filtered speed lags */
        run_ms(1000);
        double m = mean_speed(500, NULL);
        assert_true(fabs(m - (neg ? -360.0 : 360.0)) < 5.0);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(rule1_nothing_moves_at_power_up),
        cmocka_unit_test(position_moves_per_variant),
        cmocka_unit_test(replan_mid_move),
        cmocka_unit_test(base_relative_goal),
        cmocka_unit_test(speed_mode_holds_the_speed_reverses_on_bit_15_and_coasts_at_0),
        cmocka_unit_test(turned_angle_wraps),
        cmocka_unit_test(brake_stops_every_motion),
        cmocka_unit_test(brake_stops_a_coasting_motor),
        cmocka_unit_test(sleep_and_wake),
        cmocka_unit_test(speed_0_or_brake_stops_within_a_tick_after_any_commands),
        cmocka_unit_test(start_end_semantics),
        cmocka_unit_test(custom_move_goes_either_way_with_its_own_ramps),
        cmocka_unit_test(trajectory_passes_points_stops_at_reversals_and_ends_on_the_last),
        cmocka_unit_test(resolution_change_stops),
        cmocka_unit_test(holds_against_gravity),
        cmocka_unit_test(reengage_while_coasting), /* last: see there */
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
