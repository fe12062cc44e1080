/* test_invariants.c - the spec's global rules (docs/invariants.md) as invariants, checked
 * after every step of random command sequences that issue every write and command while
 * every kind of motion runs: a move, a trajectory, speed mode, homing, CUSTOM MOVE, braked,
 * asleep, unloaded, at rest. Issue 25: each feature held alone; where two met (a limit
 * written while a move runs, a mode left while the motor turns) the rules broke.
 *
 * Like test_props.c, the servo is judged only through the bus (tests/bus_host.h) and the
 * host HAL's outputs (the bridge enable and drive, the plant's shaft); its own state is
 * never looked at. A premise narrows a rule only where PROTOCOL.md itself allows it, and
 * each is stated where it is applied.
 *
 * INVARIANTS_SEQUENCES (environment) sets how many sequences (default 600), INVARIANTS_SEED
 * the first seed. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "bus_host.h"
#include "test_rng.h"

#define READ_MS 20u          /* the host reads the whole table this often while it watches */
#define SETTLE_MS 90000u     /* the longest a generated motion may take to end (see below) */
#define COUNT_SLACK 2        /* plant counts a held shaft may settle by (HOLD_BAND + 1) */

enum state {
    S_REST, S_MOVE, S_TRAJ, S_SPEED, S_HOMING, S_CUSTOM, S_BRAKED, S_ASLEEP, S_UNLOADED,
    S_COUNT
};
static const char *const state_name[S_COUNT] = {
    "rest", "move", "traj", "speed", "homing", "custom", "braked", "asleep", "unloaded",
};

enum cmd {
    C_LIMITS,      /* new limits around the shaft */
    C_LIMITS_OUT,  /* new limits that leave the shaft (or the running target) outside */
    C_SPEED_MODE,  /* both limits 0 (§6.2) */
    C_START,       /* START/END 1 */
    C_END,         /* START/END 2 */
    C_RESOLUTION,  /* register 13 */
    C_GOAL,
    C_SPEED,
    C_STOP,        /* speed 0 (rule 3) */
    C_RAMPS,
    C_TRAJ_WRITE,
    C_TRAJ_ACTION,
    C_CUSTOM,
    C_REG_ACTION,  /* REG WRITE of limits or a goal, then ACTION */
    C_SYNC_WRITE,  /* SYNC WRITE of limits or a goal */
    C_RESET,
    C_HOME,
    C_HOME_ABORT,
    C_BRAKE,       /* brake on or off */
    C_SLEEP,       /* sleep on or off */
    C_CLEAR,       /* clear unload */
    C_ZERO_SIDE,   /* register 19 */
    C_TERMINATOR,  /* register 20 */
    C_RESTART,     /* power cycle */
    C_COUNT
};
static const char *const cmd_name[C_COUNT] = {
    "limits", "lim-out", "spdmode", "start", "end", "res", "goal", "speed", "stop", "ramps",
    "trajw", "traja", "custom", "regact", "sync", "reset", "home", "home0", "brake", "sleep",
    "clear", "zside", "term", "restart",
};

/* What the host knows, from what it sent and read. */
struct host {
    const struct board *b;
    uint32_t seed;
    uint8_t t[REGS_SIZE];   /* last table read */
    int err;                /* ERR byte of that READ's answer */
    bool motion_since_power; /* rule 1: a motion command since power-up or RESET */
    bool referenced;        /* homing done since the reference was last lost */
    bool hb_stopped;        /* the heartbeat stopped whatever ran (§7.1: it stays there) */
    bool jammed;            /* fault injection: the plant's shaft is blocked */
    bool braked_outside;    /* the brake caught the shaft outside the limits (§6.3) */
    bool wheel_asked;       /* the host sent limits 0/0 since it last read others */
    bool goal_from_power_up; /* rule 1: the goal is the present position, wherever it is */
    bool have_power_goal;   /* power_goal read since the power-up */
    uint16_t power_goal;
    bool anchor_ok;         /* nothing may move: the shaft must stay at anchor */
    int64_t anchor;
    int64_t last_count;     /* plant count at the last read */
    bool at_rest;           /* the last two reads: moving 0 and the same plant count */
    uint32_t speak_us;      /* last packet the host sent (heartbeat) */
    char log[6144];
    size_t log_len;
};

static struct host H;
static unsigned long trace; /* INVARIANTS_TRACE=1: every read on stderr */
static uint32_t prng;
static int fails;
static unsigned long pairs[S_COUNT][C_COUNT];
static struct {
    unsigned long goal_in_limits, rest_in_limits, comes_to_rest, rule1, rule3_stop, rule3_brake,
        unload_off, nothing_moves, wheel;
} checked;

static uint32_t prnd(uint32_t n)
{
    uint32_t x = xorshift32(&prng);
    return n ? x % n : 0;
}

static void note(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    if (H.log_len < sizeof H.log - 1u) {
        int n = vsnprintf(&H.log[H.log_len], sizeof H.log - H.log_len, fmt, ap);
        if (n > 0)
            H.log_len += (size_t)n;
        if (H.log_len > sizeof H.log - 1u)
            H.log_len = sizeof H.log - 1u;
    }
    va_end(ap);
}

/* The rules, for the summary of which failed first at which seed. */
enum rule { R_GOAL, R_REST, R_ENDS, R_RULE1, R_RULE3, R_UNLOAD, R_STILL, R_WHEEL, R_LINK, R_COUNT };
static const char *const rule_name[R_COUNT] = {
    "I1 goal within limits", "I2 rest within limits", "I3 motion ends", "rule 1",
    "rule 3", "unload torque off", "nothing moves uncommanded", "speed mode asked for",
    "answers",
};
static unsigned long rule_fails[R_COUNT];
static uint32_t rule_seed[R_COUNT][3];

static unsigned long rule_skip; /* INVARIANTS_SKIP: a mask of rules not checked (bit r) */

static void rule_failed(enum rule r)
{
    if (rule_fails[r] < 3u)
        rule_seed[r][rule_fails[r]] = H.seed;
    rule_fails[r]++;
    fails++;
}

#define RULE(r, cond, ...)                                                                   \
    do {                                                                                     \
        if (!(cond) && !(rule_skip & (1ul << (r)))) {                                       \
            if (rule_fails[r] < 3u) {                                                        \
                fprintf(stderr, "invariants: seed %u, %s: ", H.seed, H.b->name);            \
                fprintf(stderr, __VA_ARGS__);                                                \
                fprintf(stderr, "\n  steps:%s\n", H.log);                                    \
            }                                                                                \
            rule_failed(r);                                                                  \
            return false;                                                                    \
        }                                                                                    \
    } while (0)

static struct motor_sim *plant(void)
{
    struct hal *h = bus_hal();
    motor_sim_advance(&h->motor, bus.now_us);
    return &h->motor;
}

static int64_t plant_count(void)
{
    return (int64_t)llround(plant()->theta / (2.0 * 3.14159265358979323846) * 16384.0);
}

static bool is_base(void)
{
    return H.b->variant == VARIANT_BASE;
}

static uint16_t cw(void) { return tab16(H.t, REG_CW_LIMIT); }
static uint16_t ccw(void) { return tab16(H.t, REG_CCW_LIMIT); }

static bool position_mode(void)
{
    return !is_base() && !(cw() == 0u && ccw() == 0u);
}

/* The present position as the goal register counts it (16 bits). */
static uint16_t pos16(void)
{
    return (uint16_t)tab_position(H.b, H.t);
}

static uint8_t unload_bits(void)
{
    return (uint8_t)(ERR_OVER_TEMPERATURE | ERR_OVER_CURRENT | ERR_OVER_VOLTAGE |
                     ERR_UNDER_VOLTAGE | ERR_STALL);
}

static bool unloaded(void)
{
    return H.err >= 0 && ((unsigned)H.err & H.t[REG_UNLOAD_CONDITIONS] & unload_bits());
}

/* The reference the limits are measured from is valid (§9: on a motor with photo switches,
 * only once homing has succeeded; until then positions count from power-up). */
static bool reference_valid(void)
{
    return !H.b->photo_switches || H.referenced;
}

/* One READ of the whole table, then every invariant. */
static bool observe(void)
{
    uint8_t p[2] = {0, REGS_SIZE};
    int e = bus_ins(INS_READ, p, 2);
    H.speak_us = bus.now_us;
    RULE(R_LINK, e >= 0 && bus_ans_len == REGS_SIZE, "no answer to READ 0..49");
    memcpy(H.t, bus_ans, REGS_SIZE);
    H.err = e;
    struct motor_sim *m = plant();
    int64_t c = plant_count();
    bool moving = H.t[REG_MOVING] != 0u;
    H.at_rest = !moving && c == H.last_count;
    H.last_count = c;
    if (trace)
        fprintf(stderr, "  %.3f s: moving %u, count %lld, %.4f rad/s, bridge %d, pos %d\n",
                (bus.now_us - HAL_HOST_CLOCK_START) / 1e6, moving, (long long)c, m->omega,
                m->enabled, tab_position(H.b, H.t));
    if ((H.t[REG_HOMING] >> 4) == 2u && (H.t[REG_HOMING] & 0x0Fu) == 1u)
        H.referenced = true;

    /* The brake holds where it caught the shaft (§6.3), and a limit written while braked
     * cannot move it; releasing the brake starts nothing (§6.3): it stays until the next
     * motion command. */
    if (H.t[REG_BRAKE] && position_mode() && (pos16() < cw() || pos16() > ccw()))
        H.braked_outside = true;
    /* I1 (§5.4): CW limit <= goal <= CCW limit whenever the goal is read in position mode.
     * Rule 1 (§0) overrides it after power-up: the goal starts equal to the present
     * position, wherever that is, until a goal or the limits are written. */
    if (H.goal_from_power_up && H.have_power_goal &&
        tab16(H.t, REG_GOAL_POSITION) != H.power_goal)
        H.goal_from_power_up = false;
    if (H.goal_from_power_up && !H.have_power_goal) {
        H.power_goal = tab16(H.t, REG_GOAL_POSITION);
        H.have_power_goal = true;
    }
    if (position_mode() && !H.goal_from_power_up) {
        uint16_t g = tab16(H.t, REG_GOAL_POSITION);
        checked.goal_in_limits++;
        RULE(R_GOAL, g >= cw() && g <= ccw(), "I1: goal %u read outside the limits [%u, %u]", g, cw(),
             ccw());
    }
    /* I2 (§5.4, §6.1): at rest in position mode, holding with torque, the shaft is within
     * the limits. Not where the spec lets it rest elsewhere: torque off (speed 0, sleep,
     * unload: §6.2, §6.3, §7.2), the brake that caught it outside (§6.3 "stop at once and
     * hold"), the heartbeat's stop (§7.1 "holding still"), no valid reference (§9), or a
     * jammed shaft. */
    if (position_mode() && !moving && m->enabled && !H.t[REG_BRAKE] && !H.braked_outside &&
        !H.hb_stopped && reference_valid() && !H.jammed) {
        uint16_t at = pos16();
        checked.rest_in_limits++;
        RULE(R_REST, at >= cw() && at <= ccw(), "I2: at rest at %u with torque, outside [%u, %u]", at,
             cw(), ccw());
    }
    /* §6.2: speed mode (both limits 0) only when the host wrote both limits 0. */
    if (!is_base()) {
        if (cw() || ccw()) {
            H.wheel_asked = false;
        } else {
            checked.wheel++;
            RULE(R_WHEEL, H.wheel_asked, "§6.2: limits read 0/0 (speed mode), never written so");
        }
    }
    /* Rule 1 (§0): after power-up or RESET the motor does not turn until a motion command. */
    if (!H.motion_since_power) {
        checked.rule1++;
        RULE(R_RULE1, !m->enabled && m->duty == 0, "rule 1: the bridge drives (%d) with no motion command"
             " since power-up", m->duty);
    }
    /* §7.2: an unload holds the torque off until it is cleared. */
    if (unloaded()) {
        checked.unload_off++;
        RULE(R_UNLOAD, !m->enabled, "§7.2: unloaded (ERR 0x%02x), yet the bridge is on", H.err);
    }
    /* Nothing moves without a motion command: from rest, what was sent since is not one. */
    if (H.anchor_ok) {
        checked.nothing_moves++;
        RULE(R_STILL, llabs(c - H.anchor) <= COUNT_SLACK,
             "nothing was commanded to move since the shaft rested at count %lld; now %lld",
             (long long)H.anchor, (long long)c);
    }
    return true;
}

/* Watch for ms: read the table every READ_MS (which keeps the heartbeat fed), or stay
 * silent (the heartbeat may stop the motion). */
static bool watch(uint32_t ms, bool silent)
{
    for (uint32_t i = 1; i <= ms; i++) {
        bus_run_ms(1);
        if (!silent && i % READ_MS == 0u && !observe())
            return false;
    }
    if (silent && H.t[REG_HEARTBEAT_ENABLE] && ms >= SAFETY_HEARTBEAT_TICKS)
        H.hb_stopped = true;
    if (silent)
        H.at_rest = false;
    return true;
}

static bool ok(int e)
{
    return e >= 0 && !((unsigned)e & ERR_INSTRUCTION);
}

/* A command the host sends; the caller says whether it may move the shaft (a motion
 * command, or a change of the limits that may leave the shaft outside them). */
static void sent(bool may_move)
{
    H.speak_us = bus.now_us;
    if (may_move) {
        H.anchor_ok = false;
    } else if (H.at_rest && !H.anchor_ok && !H.jammed) {
        H.anchor_ok = true; /* from rest, and nothing since may move it */
        H.anchor = plant_count();
    }
    H.at_rest = false; /* rest is known again only from reads after this command */
}

/* A motion command was sent (rule 1 counts it, accepted or not); moved: it was accepted
 * and starts a motion, which ends where the rules say, whatever stopped the shaft before. */
static void motion_command(bool moved)
{
    sent(true);
    H.motion_since_power = true;
    if (moved) {
        H.hb_stopped = false;
        H.braked_outside = false;
    }
}

/* Could a motion command start a motion now, if accepted? */
static bool may_start(void)
{
    return !unloaded() && !H.t[REG_BRAKE] && !H.t[REG_SLEEP];
}

static bool speed_set(void)
{
    return (tab16(H.t, REG_MOVING_SPEED) & 0x7FFFu) != 0u;
}

static int32_t units(double deg)
{
    return (int32_t)lround(deg * 10.0 / H.t[REG_RESOLUTION]);
}

static uint16_t speed_units(void)
{
    static const uint16_t dps[] = {60, 90, 180, 360, 720};
    int32_t u = units(dps[prnd(5)]);
    return (uint16_t)(u < 1 ? 1 : u > 0x7FFF ? 0x7FFF : u);
}

/* The board's travel in units (the arm's is its measured 420 degrees). */
static int32_t travel_units(void)
{
    int32_t deg10 = H.b->variant == VARIANT_ARM ? 4200 : H.b->max_angle_ddeg;
    return deg10 ? deg10 / H.t[REG_RESOLUTION] : units(360);
}

static int w16(uint8_t addr, uint16_t v)
{
    return bus_w16(addr, v);
}

/* New limits taken while not braked: a shaft held outside them comes back (issue 25), so
 * a stop that left it there (the brake, the heartbeat) no longer excuses it. */
static void limits_taken(int e)
{
    if (ok(e))
        H.goal_from_power_up = false; /* the goal is clamped to them from now on */
    if (ok(e) && !H.t[REG_BRAKE]) {
        H.braked_outside = false;
        H.hb_stopped = false;
    }
}

static int write_limits(uint16_t lo, uint16_t hi)
{
    if (lo == 0u && hi == 0u)
        H.wheel_asked = true;
    uint8_t d[4] = {(uint8_t)lo, (uint8_t)(lo >> 8), (uint8_t)hi, (uint8_t)(hi >> 8)};
    int e = bus_write(REG_CW_LIMIT, d, 4);
    limits_taken(e);
    return e;
}

/* Position mode with the board's whole travel as limits (a state's starting point). */
static void ensure_position_mode(void)
{
    if (!is_base() && cw() == 0u && ccw() == 0u)
        (void)write_limits(0, (uint16_t)travel_units());
}

static int start_move(void)
{
    (void)w16(REG_MOVING_SPEED, speed_units());
    if (is_base())
        return w16(REG_GOAL_POSITION, (uint16_t)(prnd(2) ? units(300) : -units(300)));
    ensure_position_mode();
    uint16_t lo = cw(), hi = ccw(), at = pos16();
    uint16_t far = at > (uint16_t)((lo + hi) / 2u) ? (uint16_t)(lo + (hi - lo) / 10u)
                                                   : (uint16_t)(hi - (hi - lo) / 10u);
    return w16(REG_GOAL_POSITION, far);
}

static int write_traj(void)
{
    uint8_t p[1 + 5 * 4], q = 0;
    uint8_t n = (uint8_t)(2 + prnd(4));
    p[q++] = n;
    for (uint8_t i = 0; i < n; i++) {
        uint16_t a = (uint16_t)prnd((uint32_t)travel_units() + 1u), v = speed_units();
        p[q++] = (uint8_t)a;
        p[q++] = (uint8_t)(a >> 8);
        p[q++] = (uint8_t)v;
        p[q++] = (uint8_t)(v >> 8);
    }
    return bus_ins(INS_TRAJ_WRITE, p, q);
}

static int custom_move(void)
{
    bool abs_move = !is_base() && prnd(2);
    uint16_t tgt = abs_move ? (uint16_t)prnd((uint32_t)travel_units() + 1u)
                            : (uint16_t)units(60 + prnd(240));
    uint16_t v = (uint16_t)(speed_units() | (!abs_move && prnd(2) ? 0x8000u : 0u));
    uint8_t p[7] = {abs_move ? 2 : 1, (uint8_t)tgt, (uint8_t)(tgt >> 8), (uint8_t)v,
                    (uint8_t)(v >> 8), (uint8_t)(5 + prnd(100)), (uint8_t)(5 + prnd(100))};
    return bus_ins(INS_CUSTOM, p, 7);
}

/* Limits for C_LIMITS (around the shaft) or C_LIMITS_OUT (the shaft outside them). */
static void pick_limits(bool around, uint16_t *lo, uint16_t *hi)
{
    int32_t t = travel_units(), at = (int16_t)pos16();
    if (at < 0)
        at = 0;
    if (around) {
        int32_t a = at - (int32_t)prnd((uint32_t)t / 2u + 1u);
        int32_t b = at + 1 + (int32_t)prnd((uint32_t)t / 2u + 1u);
        *lo = (uint16_t)(a < 0 ? 0 : a);
        *hi = (uint16_t)(b > 0x7FFF ? 0x7FFF : b);
        return;
    }
    if (at > t / 4 && prnd(2)) { /* below the shaft */
        *lo = (uint16_t)prnd((uint32_t)at / 2u);
        *hi = (uint16_t)(*lo + 1u + prnd((uint32_t)(at - *lo) / 2u));
    } else { /* above it */
        *lo = (uint16_t)(at + units(20) + (int32_t)prnd((uint32_t)t / 2u + 1u));
        *hi = (uint16_t)(*lo + 1u + prnd((uint32_t)t / 2u + 1u));
    }
}

/* What the host's commands of one kind carry: REG WRITE/ACTION and SYNC WRITE take limits
 * or a goal. */
static int reg_action(void)
{
    uint8_t p[5];
    uint8_t n;
    if (prnd(2) && !is_base()) {
        uint16_t lo, hi;
        pick_limits(prnd(2), &lo, &hi);
        p[0] = REG_CW_LIMIT;
        H.wheel_asked |= lo == 0u && hi == 0u;
        p[1] = (uint8_t)lo, p[2] = (uint8_t)(lo >> 8), p[3] = (uint8_t)hi, p[4] = (uint8_t)(hi >> 8);
        n = 5;
    } else {
        uint16_t g = (uint16_t)prnd((uint32_t)travel_units() + 1u);
        p[0] = REG_GOAL_POSITION, p[1] = (uint8_t)g, p[2] = (uint8_t)(g >> 8);
        n = 3;
    }
    int e = bus_ins(INS_REG_WRITE, p, n);
    int e2 = bus_ins(INS_ACTION, NULL, 0);
    note("(%d)", e);
    return e2;
}

static int sync_write(void)
{
    uint8_t p[2 + 2 * 5], q = 0;
    bool lim = prnd(2) && !is_base();
    uint16_t lo, hi, g = (uint16_t)prnd((uint32_t)travel_units() + 1u);
    pick_limits(prnd(2), &lo, &hi);
    H.wheel_asked |= lim && lo == 0u && hi == 0u;
    p[q++] = lim ? REG_CW_LIMIT : REG_GOAL_POSITION;
    p[q++] = lim ? 4 : 2;
    for (uint8_t id = 2; id != 0; id--) { /* another servo's slice, then ours */
        p[q++] = id == 2u ? 2u : BUS_ID;
        p[q++] = (uint8_t)(lim ? lo : g), p[q++] = (uint8_t)((lim ? lo : g) >> 8);
        if (lim)
            p[q++] = (uint8_t)hi, p[q++] = (uint8_t)(hi >> 8);
    }
    (void)bus_ins_to(PROTO_ID_BROADCAST, INS_SYNC_WRITE, p, q);
    bus_run_ms(2);
    return 0;
}

/* After RESET or a power cycle: the fast link again (§4.5 restores the factory baud). */
static bool relink(void)
{
    if (bus_ins(INS_PING, NULL, 0) == 1)
        return true;
    bus.host_baud = link_baud(H.b, 0);
    if (!ok(bus_w8(REG_RETURN_DELAY, 0)) || !ok(bus_w8(REG_BAUD_RATE, BUS_FAST_CODE)))
        RULE(R_LINK, 0, "no answer after a RESET or power cycle, at the fast or the factory baud");
    bus_follow_baud(BUS_FAST_BAUD);
    return true;
}

static void powered_up(void)
{
    H.goal_from_power_up = true; /* until the goal register reads another value */
    H.have_power_goal = false;
    H.motion_since_power = false;
    H.referenced = false;
    H.hb_stopped = false;
    H.braked_outside = false;
    H.anchor_ok = false; /* the shaft may still coast through a restart */
}

/* Issue one command of kind c; the state it met is counted by the caller. */
static bool command(enum cmd c)
{
    uint16_t lo, hi;
    int e = 0;
    switch (c) {
    case C_LIMITS:
    case C_LIMITS_OUT: {
        pick_limits(c == C_LIMITS, &lo, &hi);
        int32_t at = (int16_t)pos16(); /* a foot's position may be negative: never within */
        e = write_limits(lo, hi);
        note(" lim%u..%u:%d", lo, hi, e);
        sent(at < lo || at > hi); /* a shaft held outside them comes back */
        break;
    }
    case C_SPEED_MODE:
        e = write_limits(0, 0);
        note(" lim0:%d", e);
        sent(false);
        break;
    case C_START:
    case C_END: {
        uint8_t what = c == C_START ? 1u : 2u;
        e = bus_ins(INS_START_END, &what, 1);
        note(" se%u:%d", what, e);
        limits_taken(e);
        sent(false);
        break;
    }
    case C_RESOLUTION: {
        static const uint8_t res[] = {1, 5, 10, 20};
        uint8_t r = res[prnd(4)];
        bool change = r != H.t[REG_RESOLUTION]; /* the same value changes nothing (§5) */
        bool outside = position_mode() && (pos16() < cw() || pos16() > ccw());
        e = bus_w8(REG_RESOLUTION, r);
        note(" res%u:%d", r, e);
        if (change)
            limits_taken(e);
        sent(change && outside); /* the limits apply again: a shaft held outside comes back */
        break;
    }
    case C_GOAL:
        e = start_move();
        note(" goal:%d", e);
        motion_command(ok(e) && may_start());
        break;
    case C_SPEED: {
        uint16_t v = (uint16_t)(speed_units() | (prnd(2) ? 0x8000u : 0u));
        e = w16(REG_MOVING_SPEED, v);
        note(" speed%c%u:%d", v & 0x8000u ? '-' : '+', v & 0x7FFFu, e);
        motion_command(ok(e) && may_start() && !position_mode());
        break;
    }
    case C_STOP: {
        e = w16(REG_MOVING_SPEED, (uint16_t)(prnd(2) ? 0x8000u : 0u));
        note(" stop:%d", e);
        sent(false);
        struct motor_sim *m = plant();
        checked.rule3_stop++;
        RULE(R_RULE3, ok(e), "rule 3: speed 0 refused (%d)", e);
        RULE(R_RULE3, !m->enabled && m->duty == 0, "rule 3: speed 0 answered, the bridge still drives %d",
             m->duty);
        break;
    }
    case C_RAMPS: {
        uint8_t a = is_base() ? REG_BASE_ACCELERATION : REG_ACCELERATION;
        uint8_t d[2] = {(uint8_t)(5 + prnd(200)), (uint8_t)(5 + prnd(200))};
        e = bus_write(a, d, 2);
        note(" ramps%u/%u:%d", d[0], d[1], e);
        sent(false);
        break;
    }
    case C_TRAJ_WRITE:
        e = write_traj();
        note(" trajw:%d", e);
        sent(false);
        break;
    case C_TRAJ_ACTION:
        if (prnd(2))
            (void)write_traj();
        e = bus_ins(INS_TRAJ_ACTION, NULL, 0);
        note(" traja:%d", e);
        motion_command(ok(e));
        break;
    case C_CUSTOM:
        e = custom_move();
        note(" custom:%d", e);
        motion_command(ok(e));
        break;
    case C_REG_ACTION:
        e = reg_action();
        note(" regact:%d", e);
        motion_command(ok(e) && may_start() && speed_set());
        break;
    case C_SYNC_WRITE:
        e = sync_write();
        note(" sync");
        motion_command(may_start() && speed_set());
        break;
    case C_RESET:
        e = bus_ins(INS_RESET, NULL, 0);
        note(" reset:%d", e);
        powered_up();
        bus_run_ms(20);
        if (!relink())
            return false;
        break;
    case C_HOME:
        e = bus_w8(REG_HOMING, 1);
        note(" home:%d", e);
        motion_command(ok(e) && H.b->photo_switches && may_start());
        H.referenced = false;
        break;
    case C_HOME_ABORT:
        e = bus_w8(REG_HOMING, 0);
        note(" home0:%d", e);
        sent(false);
        break;
    case C_BRAKE: {
        uint8_t on = !H.t[REG_BRAKE];
        e = bus_w8(REG_BRAKE, on);
        note(" brake%u:%d", on, e);
        if (on) {
            uint16_t at = pos16();
            motion_command(false); /* it holds with torque, even from a coast (§6.3) */
            H.braked_outside = position_mode() && (at < cw() || at > ccw());
        } else {
            sent(false);
        }
        break;
    }
    case C_SLEEP: {
        uint8_t on = !H.t[REG_SLEEP];
        e = bus_w8(REG_SLEEP, on);
        note(" sleep%u:%d", on, e);
        sent(false);
        break;
    }
    case C_CLEAR:
        e = bus_w8(REG_CLEAR_UNLOAD, 1);
        note(" clear:%d", e);
        sent(false);
        break;
    case C_ZERO_SIDE:
        e = bus_w8(REG_HOMING_ZERO_SIDE, (uint8_t)(1 + prnd(2)));
        note(" zside:%d", e);
        sent(false);
        H.referenced = false; /* a change mirrors the motor: the reference is gone */
        break;
    case C_TERMINATOR:
        e = bus_w8(REG_RS485_TERMINATION, (uint8_t)prnd(2));
        note(" term:%d", e);
        sent(false);
        break;
    case C_RESTART:
        note(" restart");
        vbus_power_cycle(&bus, 0);
        powered_up();
        bus_run_ms(5);
        if (!relink())
            return false;
        break;
    default:
        break;
    }
    (void)e;
    return true;
}

/* The state the host sees now: what it set up, confirmed by what it reads. */
static enum state observed(enum state want)
{
    if ((H.t[REG_HOMING] >> 4) == 1u)
        return S_HOMING;
    if (unloaded())
        return S_UNLOADED;
    if (H.t[REG_BRAKE])
        return S_BRAKED;
    if (H.t[REG_SLEEP])
        return S_ASLEEP;
    if (!H.t[REG_MOVING])
        return S_REST;
    if (want == S_MOVE || want == S_TRAJ || want == S_SPEED || want == S_CUSTOM)
        return want;
    return S_REST;
}

static void fault_on(void)
{
    bus_hal()->temperature_dc = 1000; /* 100 C, over the factory limit of 80 C */
}

static void faults_off(void)
{
    struct hal *h = bus_hal();
    h->temperature_dc = 250;
    h->motor.blocked = false;
    H.jammed = false;
}

/* Bring the servo into state s (as far as it lets itself: a refused command leaves it
 * elsewhere, and the state is then counted as what the host reads). */
static bool setup(enum state s)
{
    int e;
    switch (s) {
    case S_MOVE:
        e = start_move();
        note(" [move:%d]", e);
        motion_command(ok(e) && may_start());
        break;
    case S_TRAJ:
        ensure_position_mode();
        (void)write_traj();
        e = bus_ins(INS_TRAJ_ACTION, NULL, 0);
        note(" [traj:%d]", e);
        motion_command(ok(e));
        break;
    case S_SPEED:
        if (!is_base())
            (void)write_limits(0, 0);
        (void)bus_w8(REG_MOVE_WITHOUT_REFERENCE, 1);
        e = w16(REG_MOVING_SPEED, (uint16_t)(speed_units() | (prnd(2) ? 0x8000u : 0u)));
        note(" [speed:%d]", e);
        motion_command(ok(e) && may_start());
        break;
    case S_HOMING:
        e = bus_w8(REG_HOMING, 1);
        note(" [home:%d]", e);
        motion_command(ok(e) && H.b->photo_switches && may_start());
        H.referenced = false;
        break;
    case S_CUSTOM:
        ensure_position_mode();
        e = custom_move();
        note(" [custom:%d]", e);
        motion_command(ok(e));
        break;
    case S_BRAKED:
    case S_ASLEEP:
        if (prnd(3)) {
            e = start_move();
            motion_command(ok(e) && may_start());
            if (!watch(50 + prnd(300), false))
                return false;
        }
        e = bus_w8(s == S_BRAKED ? REG_BRAKE : REG_SLEEP, 1);
        note(" [%s:%d]", s == S_BRAKED ? "brake" : "sleep", e);
        if (s == S_BRAKED) {
            uint16_t at = pos16();
            motion_command(false);
            H.braked_outside = position_mode() && (at < cw() || at > ccw());
        } else {
            sent(false);
        }
        break;
    case S_UNLOADED:
        if (prnd(2)) {
            e = start_move();
            motion_command(ok(e) && may_start());
        }
        fault_on();
        note(" [fault]");
        if (!watch(700, false))
            return false;
        if (prnd(2))
            faults_off(); /* the cause goes; the unload stays latched until cleared */
        break;
    default:
        break;
    }
    return true;
}

/* The end of a sequence: the host keeps talking (the heartbeat fed) and waits for the
 * motion to end. In position mode with torque on, every motion ends (§6.2: only both limits
 * 0 turn the motor continuously), and it ends within the limits (I2). SETTLE_MS bounds the
 * longest motion the generator can ask for: 5 trajectory points over the whole travel at
 * 60 deg/s and ramps of at least 50 deg/s^2. */
static bool settle(void)
{
    faults_off();
    for (uint32_t t = 0; t < SETTLE_MS; t += READ_MS) {
        if (!watch(READ_MS, false))
            return false;
        if (!H.t[REG_MOVING] && H.at_rest)
            break;
    }
    if (position_mode() && plant()->enabled && reference_valid()) {
        checked.comes_to_rest++;
        RULE(R_ENDS, !H.t[REG_MOVING], "I3: position mode [%u, %u], still moving %u s after the last "
             "command (speed %d)", cw(), ccw(), SETTLE_MS / 1000u,
             tab_speed(H.t));
    }
    return true;
}

/* Starting points: each variant powered up on the fast link, and for the ones with photo
 * switches also homed; a sequence starts from a copy. */
static struct vbus snap[BOARD_COUNT][2];
static bool snap_ok[BOARD_COUNT][2];

static bool start(unsigned bi, bool homed)
{
    const struct board *b = board_all[bi];
    unsigned hm = homed && b->photo_switches;
    if (!snap_ok[bi][hm]) {
        if (!bus_open(b))
            return false;
        if (hm && bus_home(20000) != 2u)
            return false;
        uint8_t t[REGS_SIZE];
        if (!bus_read_table(t) || t[REG_MOVING])
            return false; /* premise: at rest, answering */
        snap[bi][hm] = bus;
        snap_ok[bi][hm] = true;
    }
    bus = snap[bi][hm];
    H.referenced = hm != 0u;
    H.motion_since_power = hm != 0u;
    return true;
}

static bool sequence(uint32_t seed)
{
    memset(&H, 0, sizeof H);
    H.seed = seed;
    prng = seed * 2654435761u + 0x9E3779B9u;
    if (!prng)
        prng = 1;
    unsigned bi = prnd(BOARD_COUNT);
    H.b = board_all[bi];
    bool homed = prnd(8) != 0u;
    if (!start(bi, homed)) {
        fprintf(stderr, "invariants: seed %u: %s does not start\n", seed, H.b->name);
        fails++;
        return false;
    }
    note(" %s%s", H.b->name, H.b->photo_switches && homed ? " homed" : "");
    if (!observe())
        return false;
    H.last_count = plant_count();
    unsigned n = 2u + prnd(3);
    for (unsigned i = 0; i < n; i++) {
        enum state want = (enum state)prnd(S_COUNT);
        if (!setup(want) || !watch(20 + prnd(400), false))
            return false;
        enum state got = observed(want);
        enum cmd c = (enum cmd)prnd(C_COUNT);
        pairs[got][c]++;
        note(" {%s}", state_name[got]);
        if (!command(c))
            return false;
        bool silent = prnd(6) == 0u;
        if (!watch(silent ? 600 + prnd(600) : 100 + prnd(2500), silent))
            return false;
        if (got == S_UNLOADED || prnd(3) == 0u) { /* back to work: cause gone, cleared */
            faults_off();
            if (!watch(2500, false))
                return false;
            (void)bus_w8(REG_CLEAR_UNLOAD, 1);
            (void)bus_w8(REG_BRAKE, 0);
            (void)bus_w8(REG_SLEEP, 0);
            sent(false);
            note(" [clear]");
        }
    }
    return settle();
}

static unsigned long env_or(const char *name, unsigned long dflt)
{
    const char *v = getenv(name);
    return v && *v ? strtoul(v, NULL, 0) : dflt;
}

static void print_pairs(void)
{
    print_message("invariants: commands met in each state (state x command):\n%-9s", "");
    for (unsigned c = 0; c < C_COUNT; c++)
        print_message("%8s", cmd_name[c]);
    print_message("\n");
    for (unsigned s = 0; s < S_COUNT; s++) {
        print_message("%-9s", state_name[s]);
        for (unsigned c = 0; c < C_COUNT; c++)
            print_message("%8lu", pairs[s][c]);
        print_message("\n");
    }
}

static void global_rules_hold(void **state)
{
    (void)state;
    unsigned long n = env_or("INVARIANTS_SEQUENCES", 600), seed0 = env_or("INVARIANTS_SEED", 1);
    unsigned long clean = 0;
    unsigned long max_fails = env_or("INVARIANTS_MAX_FAILS", 5);
    rule_skip = env_or("INVARIANTS_SKIP", 0);
    trace = env_or("INVARIANTS_TRACE", 0);
    for (unsigned long i = 0; i < n && (unsigned long)fails < max_fails; i++)
        if (sequence((uint32_t)(seed0 + i)))
            clean++;
    print_pairs();
    print_message("invariants: %lu sequences from seed %lu, %lu clean\n", clean + (unsigned long)fails,
                  seed0, clean);
    print_message("invariants: checks: I1 %lu, I2 %lu, I3 %lu, rule 1 %lu, rule 3 %lu, unload %lu, "
                  "nothing moves %lu, wheel %lu\n",
                  checked.goal_in_limits, checked.rest_in_limits, checked.comes_to_rest,
                  checked.rule1, checked.rule3_stop, checked.unload_off, checked.nothing_moves,
                  checked.wheel);
    for (unsigned r = 0; r < R_COUNT; r++)
        if (rule_fails[r])
            print_message("invariants: %-26s failed %lu times, first at seeds %u %u %u\n",
                          rule_name[r], rule_fails[r], rule_seed[r][0], rule_seed[r][1],
                          rule_seed[r][2]);
    assert_int_equal(fails, 0);
    if (n >= 300u) { /* premise: every state met every command, and every rule its situation */
        for (unsigned s = 0; s < S_COUNT; s++)
            for (unsigned c = 0; c < C_COUNT; c++)
                if (!pairs[s][c])
                    fail_msg("no sequence issued %s while %s", cmd_name[c], state_name[s]);
        assert_true(checked.goal_in_limits > n && checked.rest_in_limits > n &&
                    checked.comes_to_rest > n / 6u && checked.rule1 > n / 10u &&
                    checked.rule3_stop > n / 20u && checked.unload_off > n / 10u &&
                    checked.nothing_moves > n);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(global_rules_hold),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
