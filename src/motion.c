/* motion.c - the motion layer (PROTOCOL.md §4.6-§4.8, §6): turns register writes and
 * motion instructions into a planned reference, closes the position loop on the motor
 * once per control tick, and keeps the present-state registers up to date.
 *
 * The three rules of §0: at power-up the motor is off and the goal equals the present
 * position; a speed of 0 drops the drive to zero in the tick it arrives and the brake
 * freezes the reference where the shaft is; releasing the brake or waking starts
 * nothing. Heartbeat expiry and protection unloads (safety.c) and homing (§9) act here
 * too. Everything runs in the main loop. */
#include "hal.h"
#include "motion.h"
#include "proto.h"
#include "safety.h"
#include "servo.h"

#define MAX_SPEED_DPS 1080 /* what the reference may ask for, degrees/s at the output */
#define TICKS_PER_S (1000000 / (int32_t)MOTION_TICK_US)

/* Controller gains, duty per mille: feed-forward per count/tick of reference speed,
 * friction feed-forward, proportional per count of position error, damping per
 * count/tick of speed error. Tuned on the reference gearmotor (hal/host/motor_sim.c). */
#define KFF 2
#define KFRICTION 30
#define KP 8
#define KD 60
#define DEBOUNCE_TICKS 5   /* photo switches: stable this long to count */
#define KI_SHIFT 2         /* integral gain 1/4 per count per tick, only at rest, */
#define INTEGRAL_MAX 1200  /* worth at most 300 per mille: beats static friction */

static uint32_t cpr(const struct servo *s)
{
    return s->board->counts_per_rev;
}

static uint8_t resolution(const struct servo *s)
{
    return s->regs.mem[REG_RESOLUTION];
}

/* Position units (register 13 x 0.1 degree) to counts, and back, rounded. */
static int64_t units_to_counts(const struct servo *s, int32_t units)
{
    int64_t num = (int64_t)units * resolution(s) * cpr(s);
    return (num + (num >= 0 ? 1800 : -1800)) / 3600;
}

static int32_t counts_to_units(const struct servo *s, int64_t counts)
{
    int64_t den = (int64_t)resolution(s) * cpr(s);
    int64_t num = counts * 3600;
    return (int32_t)((num + (num >= 0 ? den / 2 : -den / 2)) / den);
}

/* Speed magnitude in units/s to counts/tick x 2^24, capped at MAX_SPEED_DPS. */
static int32_t speed_q24(const struct servo *s, uint16_t units_per_s)
{
    int64_t max = ((int64_t)MAX_SPEED_DPS * cpr(s) << PLANNER_SHIFT) / ((int64_t)360 * TICKS_PER_S);
    int64_t v = ((int64_t)units_per_s * resolution(s) * cpr(s) << PLANNER_SHIFT) /
                ((int64_t)3600 * TICKS_PER_S);
    return (int32_t)(v > max ? max : v);
}

/* Acceleration register (10 degree/s^2; 0 = no ramp) to counts/tick^2 x 2^24. */
static int32_t accel_q24(const struct servo *s, uint8_t reg, int32_t vmax)
{
    if (reg == 0)
        return vmax > 0 ? vmax : 1; /* no ramp: full speed in one tick */
    int64_t a = ((int64_t)reg * 10 * cpr(s) << PLANNER_SHIFT) /
                (360 * (int64_t)TICKS_PER_S * TICKS_PER_S);
    return a > 0 ? (int32_t)a : 1;
}

static uint8_t acc_reg(const struct servo *s)
{
    return s->board->variant == VARIANT_BASE ? REG_BASE_ACCELERATION : REG_ACCELERATION;
}

static void set_limits(struct servo *s, uint16_t speed)
{
    struct motion *m = &s->motion;
    m->lim.vmax = speed_q24(s, speed & 0x7FFFu);
    if (m->lim.vmax < 1)
        m->lim.vmax = 1;
    uint8_t a = acc_reg(s);
    m->lim.acc = accel_q24(s, s->regs.mem[a], m->lim.vmax);
    m->lim.dec = accel_q24(s, s->regs.mem[a + 1u], m->lim.vmax);
}

/* The present position in units, as registers 36 and 40 report it. */
static int32_t present_units(const struct servo *s)
{
    return counts_to_units(s, s->motion.counts - s->motion.zero);
}

static bool may_start(const struct servo *s)
{
    return !s->regs.mem[REG_BRAKE] && !s->regs.mem[REG_SLEEP] && !safety_unloaded(s);
}

/* Register 49 (§5.1): a motor with photo switches moves only after homing, except in
 * speed mode when register 49 allows it. */
static bool referenced_for(const struct servo *s, bool speed_mode)
{
    return !s->board->photo_switches || s->motion.referenced ||
           (speed_mode && s->regs.mem[REG_MOVE_WITHOUT_REFERENCE]);
}

/* Homing is over: status nibble of register 24, the written nibble kept. */
static void homing_status(struct servo *s, uint8_t status)
{
    s->regs.mem[REG_HOMING] = (uint8_t)(((uint32_t)status << 4) | (s->regs.mem[REG_HOMING] & 0x0Fu));
}

static void homing_fail(struct servo *s)
{
    s->motion.referenced = 0;
    homing_status(s, HOMING_FAILED);
}

/* Start driving from wherever the shaft is, without a jump in velocity. */
static void engage(struct servo *s)
{
    struct motion *m = &s->motion;
    if (m->mode == MOTION_OFF) {
        m->plan.pos = m->counts * PLANNER_ONE;
        m->plan.vel = (int32_t)((int64_t)m->vel_q8 * (PLANNER_ONE >> 8));
        m->integral = 0;
        hal_motor_enable(s->hal, true);
    }
}

/* Torque off at once (speed 0, sleep, RESET). */
static void coast(struct servo *s)
{
    struct motion *m = &s->motion;
    if (m->mode == MOTION_HOME)
        homing_fail(s); /* aborted */
    m->mode = MOTION_OFF;
    m->duty = 0;
    m->plan.vel = 0;
    hal_motor_drive(s->hal, 0);
    hal_motor_enable(s->hal, false);
}

/* Stop at once and hold where the shaft is (brake, resolution change). */
static void hold_here(struct servo *s)
{
    struct motion *m = &s->motion;
    if (m->mode == MOTION_HOME)
        homing_fail(s); /* aborted */
    if (m->mode == MOTION_OFF)
        return;
    m->plan.pos = m->counts * PLANNER_ONE;
    m->plan.vel = 0;
    m->mode = MOTION_HOLD;
}

/* Brake (§6.3): stop at once and hold with torque, from any state, coasting included
 * (not while asleep or unloaded: torque stays off then). */
static void brake_hold(struct servo *s)
{
    if (s->motion.mode == MOTION_OFF && !s->regs.mem[REG_SLEEP] && !safety_unloaded(s)) {
        engage(s);
        s->motion.mode = MOTION_HOLD;
    }
    hold_here(s);
}

/* Ramp down with the deceleration, then hold (heartbeat, end of homing). */
static void stop_soft(struct servo *s)
{
    struct motion *m = &s->motion;
    if (m->mode != MOTION_OFF && m->mode != MOTION_HOLD)
        m->mode = MOTION_STOP;
}

static void start_homing(struct servo *s)
{
    struct motion *m = &s->motion;
    homing_status(s, HOMING_RUNNING);
    m->referenced = 0;
    if (!s->board->photo_switches || !may_start(s)) {
        homing_fail(s);
        return;
    }
    engage(s);
    m->mode = MOTION_HOME;
    m->home_phase = (s->regs.mem[REG_PHOTO_SWITCHES] & 1u) ? HOME_BACKOFF : HOME_SEEK;
    m->home_from = m->counts;
    uint16_t dps = s->board->homing_dps;
    m->lim.vmax = (int32_t)(((int64_t)dps * cpr(s) << PLANNER_SHIFT) / ((int64_t)360 * TICKS_PER_S));
    uint8_t a = acc_reg(s);
    m->lim.acc = accel_q24(s, s->regs.mem[a] ? s->regs.mem[a] : 36u, m->lim.vmax);
    m->lim.dec = accel_q24(s, s->regs.mem[a + 1u] ? s->regs.mem[a + 1u] : 36u, m->lim.vmax);
    m->speed_target = m->home_phase == HOME_BACKOFF ? m->lim.vmax : -m->lim.vmax;
}

/* One tick of homing (§9), after the switches were read. */
static void homing_tick(struct servo *s)
{
    struct motion *m = &s->motion;
    uint8_t sw = s->regs.mem[REG_PHOTO_SWITCHES];
    int64_t travel = m->counts - m->home_from;
    int64_t max = (int64_t)s->board->homing_travel_deg * cpr(s) / 360;
    if (sw == 3u || travel > max || travel < -max) {
        hold_here(s); /* both switches at once, or a switch not found: failed */
        return;
    }
    switch (m->home_phase) {
    case HOME_BACKOFF:
        if (!(sw & 1u)) {
            m->home_phase = HOME_SEEK;
            m->home_from = m->counts;
            m->speed_target = -m->lim.vmax;
        }
        break;
    case HOME_SEEK:
        if (sw & 1u) { /* zero: positions count up from here toward the end */
            m->zero = m->sw_edge;
            m->home_phase = HOME_REVERSE;
            m->home_from = m->counts;
            m->speed_target = m->lim.vmax;
        }
        break;
    case HOME_REVERSE:
        if (sw & 2u) {
            int32_t end = counts_to_units(s, m->sw_edge - m->zero);
            if (end < 1 || end > 0x7FFF) {
                hold_here(s);
                return;
            }
            regs_set(&s->regs, REG_CW_LIMIT, 0);
            regs_set(&s->regs, REG_CCW_LIMIT, (uint16_t)end); /* stored at the pass's end */
            m->target = m->sw_edge * PLANNER_ONE; /* stop and hold at the end itself */
            regs_set(&s->regs, REG_GOAL_POSITION, (uint16_t)end);
            m->home_phase = HOME_END;
        }
        break;
    default: /* HOME_END: switch 2 was seen past its edge: back onto the end, then done */
        if (planner_step_to(&m->plan, m->target, &m->lim)) {
            m->referenced = 1;
            homing_status(s, HOMING_DONE);
            m->mode = MOTION_HOLD;
        }
        return;
    }
    planner_step_speed(&m->plan, m->speed_target, &m->lim);
}

/* A move to an absolute position in units (already clamped), at speed. */
static void start_move(struct servo *s, int32_t units, uint16_t speed)
{
    struct motion *m = &s->motion;
    if ((speed & 0x7FFFu) == 0u || !may_start(s) || !referenced_for(s, false))
        return; /* a goal with speed 0 (or braked, asleep) is stored, nothing moves */
    engage(s);
    set_limits(s, speed);
    m->target = (m->zero + units_to_counts(s, units)) * PLANNER_ONE;
    m->mode = MOTION_MOVE;
}

static void start_speed(struct servo *s, uint16_t speed)
{
    struct motion *m = &s->motion;
    if ((speed & 0x7FFFu) == 0u) {
        coast(s); /* rule 3; §6.2: a stop without torque */
        return;
    }
    if (!may_start(s) || !referenced_for(s, true))
        return;
    engage(s);
    set_limits(s, speed);
    m->speed_target = (speed & 0x8000u) ? -m->lim.vmax : m->lim.vmax;
    m->mode = MOTION_SPEED;
}

/* Goal register written: absolute move, or on the base a move relative to the present
 * angle (§6.1). */
static void goal_written(struct servo *s)
{
    uint16_t goal = regs_get(&s->regs, REG_GOAL_POSITION);
    uint16_t speed = regs_get(&s->regs, REG_MOVING_SPEED);
    if (s->board->variant == VARIANT_BASE)
        start_move(s, present_units(s) + (int16_t)goal, speed);
    else if (!regs_speed_mode(&s->regs))
        start_move(s, goal, speed);
}

static void speed_written(struct servo *s)
{
    struct motion *m = &s->motion;
    uint16_t speed = regs_get(&s->regs, REG_MOVING_SPEED);
    if ((speed & 0x7FFFu) == 0u) {
        coast(s);
    } else if (regs_speed_mode(&s->regs) && m->mode != MOTION_MOVE) {
        start_speed(s, speed);
    } else if (m->mode == MOTION_MOVE || m->mode == MOTION_TRAJ) {
        set_limits(s, speed); /* a new cruise speed, re-planned from here */
    }
}

void motion_init(struct servo *s)
{
    struct motion *m = &s->motion;
    *m = (struct motion){0};
    m->raw = hal_motor_position(s->hal);
    m->counts = 0;
    m->zero = 0;
    m->tick_us = hal_clock_us(s->hal);
    m->sign = s->regs.mem[REG_HOMING_ZERO_SIDE] == 2u ? -1 : 1;
    coast(s); /* rule 1: the motor is off until a command asks for motion */
    regs_set(&s->regs, REG_GOAL_POSITION, regs_present_position(&s->regs));
}

static bool touches(uint8_t addr, uint8_t n, uint8_t reg)
{
    return reg >= addr && reg < addr + n;
}

bool motion_write_allowed(const struct servo *s, uint8_t addr, const uint8_t *data, uint8_t n)
{
    if (touches(addr, n, REG_CLEAR_UNLOAD) && !safety_may_clear(s))
        return false; /* the condition is still there */
    bool unloaded = safety_unloaded(s) && !touches(addr, n, REG_CLEAR_UNLOAD);
    if (touches(addr, n, REG_HOMING) && data[REG_HOMING - addr] == 1u && unloaded)
        return false;
    if (touches(addr, n, REG_GOAL_POSITION) &&
        (unloaded || !referenced_for(s, false)))
        return false;
    if (touches(addr, n, REG_MOVING_SPEED)) {
        uint8_t i = (uint8_t)(REG_MOVING_SPEED - addr);
        bool stop = (proto_get16(&data[i]) & 0x7FFFu) == 0u; /* rule 3: never refused */
        /* In position mode the speed only sets the cruise speed: it starts nothing. */
        if (!stop && regs_speed_mode(&s->regs) && (unloaded || !referenced_for(s, true)))
            return false;
    }
    return true;
}

void motion_on_write(struct servo *s, uint8_t addr, uint8_t n)
{
    struct motion *m = &s->motion;
    if (touches(addr, n, REG_CLEAR_UNLOAD))
        safety_clear(s); /* nothing moves until the next motion command */
    if (touches(addr, n, REG_HOMING_ZERO_SIDE) &&
        m->sign != (s->regs.mem[REG_HOMING_ZERO_SIDE] == 2u ? -1 : 1)) {
        coast(s); /* the motor is mirrored from now on: the reference is gone */
        m->sign = (int8_t)-m->sign;
        m->counts = -m->counts;
        m->zero = -m->zero;
        m->referenced = 0;
    }
    if (touches(addr, n, REG_HOMING)) {
        if (s->regs.mem[REG_HOMING] & 0x0Fu)
            start_homing(s);
        else if (m->mode == MOTION_HOME)
            hold_here(s); /* writing 0 aborts */
    }
    if (touches(addr, n, REG_SLEEP) && s->regs.mem[REG_SLEEP])
        coast(s);
    if (touches(addr, n, REG_BRAKE) && s->regs.mem[REG_BRAKE])
        brake_hold(s);
    if (touches(addr, n, REG_RESOLUTION)) {
        hold_here(s); /* §5: a resolution change stops any motion */
        return;
    }
    uint8_t a = acc_reg(s);
    if ((touches(addr, n, a) || touches(addr, n, (uint8_t)(a + 1u))) && m->mode != MOTION_OFF)
        set_limits(s, regs_get(&s->regs, REG_MOVING_SPEED));
    if (touches(addr, n, REG_GOAL_POSITION))
        goal_written(s);
    else if (touches(addr, n, REG_MOVING_SPEED))
        speed_written(s);
}

uint8_t motion_start_end(struct servo *s, uint8_t what)
{
    struct motion *m = &s->motion;
    if (what == 1u) {
        m->zero = m->counts; /* the present position becomes 0 */
        m->plan.pos = m->counts * PLANNER_ONE;
        m->target = m->plan.pos;
        regs_set(&s->regs, REG_CW_LIMIT, 0);
    } else {
        int32_t here = present_units(s);
        if (here < (int32_t)regs_get(&s->regs, REG_CW_LIMIT) || here > 0x7FFF)
            return ERR_INSTRUCTION;
        regs_set(&s->regs, REG_CCW_LIMIT, (uint16_t)here);
    }
    return 0; /* both limits are stored at the end of the pass (§4.6) */
}

/* Trajectory: from point i, the last point reached without a change of direction. */
static uint8_t traj_run_end(const struct servo *s, uint8_t i, int64_t from)
{
    const struct traj *t = &s->traj;
    int64_t prev = from;
    int dir = 0;
    uint8_t j = i;
    for (; j < t->count; j++) {
        int64_t p = units_to_counts(s, t->pt[j].angle) * PLANNER_ONE;
        int d = p > prev ? 1 : p < prev ? -1 : 0;
        if (dir && d && d != dir)
            break;
        if (d)
            dir = d;
        prev = p;
    }
    return (uint8_t)(j - 1u);
}

static void traj_segment(struct servo *s)
{
    struct motion *m = &s->motion;
    m->traj_stop = traj_run_end(s, m->traj_next, m->plan.pos);
    m->target = (m->zero + units_to_counts(s, s->traj.pt[m->traj_stop].angle)) * PLANNER_ONE;
    set_limits(s, s->traj.pt[m->traj_next].speed);
}

uint8_t motion_traj_action(struct servo *s)
{
    struct motion *m = &s->motion;
    if (!may_start(s) || !referenced_for(s, false))
        return ERR_INSTRUCTION;
    engage(s);
    m->traj_next = 0;
    m->mode = MOTION_TRAJ;
    traj_segment(s);
    return 0;
}

uint8_t motion_custom_move(struct servo *s, const struct custom_move *cm)
{
    bool stop = (cm->speed & 0x7FFFu) == 0u;
    if (!stop && (!may_start(s) || !referenced_for(s, false)))
        return ERR_INSTRUCTION; /* refused: nothing changes, the ramps included (§3.2) */
    if (cm->has_ramps) {
        uint8_t a = acc_reg(s);
        regs_set(&s->regs, a, cm->acc); /* §4.8: written into the ramp registers */
        regs_set(&s->regs, (uint8_t)(a + 1u), cm->dec);
    }
    if (stop) {
        coast(s); /* rule 3: a speed of 0 stops */
        return 0;
    }
    int32_t target;
    if (cm->absolute) {
        target = regs_clamp_goal(&s->regs, cm->target);
    } else {
        int32_t rel = (cm->speed & 0x8000u) ? -(int32_t)cm->target : (int32_t)cm->target;
        target = present_units(s) + rel;
        if (!regs_speed_mode(&s->regs))
            target = regs_clamp_goal(&s->regs, (uint16_t)(target < 0 ? 0 : target > 0xFFFF
                                                                                ? 0xFFFF
                                                                                : target));
    }
    start_move(s, target, (uint16_t)(cm->speed & 0x7FFFu));
    return 0;
}

void motion_torque_off(struct servo *s)
{
    coast(s);
}

void motion_reset(struct servo *s)
{
    coast(s);
    s->motion.zero = s->motion.counts;
    s->motion.referenced = 0; /* §4.5: RESET clears the homing reference */
}

/* Read the sensor: unwrap the count and filter the measured speed. */
static void measure(struct servo *s)
{
    struct motion *m = &s->motion;
    int32_t raw = hal_motor_position(s->hal);
    int32_t delta = (int32_t)((uint32_t)raw - (uint32_t)m->raw) * m->sign;
    m->raw = raw;
    m->counts += delta;
    /* First-order filter, 1/8 per tick, its division remainder carried to the next tick:
     * no bias, and a shaft at rest reads exactly 0 (truncation alone left up to 7/256 of
     * a count per tick for ever: 1 unit/s). */
    int32_t dv = delta * 256 - m->vel_q8 + m->vel_rem;
    m->vel_q8 += dv / 8;
    m->vel_rem = (int8_t)(dv % 8);
    uint8_t sw = hal_photo_switches(s->hal) & 3u;
    if (sw != m->sw_raw) {
        m->sw_raw = sw;
        m->sw_count = 0;
        m->sw_edge = m->counts;
    } else if (m->sw_count < DEBOUNCE_TICKS && ++m->sw_count == DEBOUNCE_TICKS) {
        s->regs.mem[REG_PHOTO_SWITCHES] = sw;
    }
}

/* Position loop with speed and friction feed-forward, and an integral term while the
 * reference rests (so static friction cannot leave a standing error); returns the duty,
 * limited so the winding current stays under 80 % of register 12: the current follows
 * the difference between the drive and the back-EMF, which the speed feed-forward
 * constant measures in duty units. So a reversal at speed or a hard stop brakes at the
 * current limit instead of tripping the over-current protection. */
static int16_t control(const struct servo *s, struct motion *m)
{
    int64_t ref = (m->plan.pos + PLANNER_ONE / 2) >> PLANNER_SHIFT;
    int64_t err = ref - m->counts;
    if (m->plan.vel == 0 && err > -INTEGRAL_MAX && err < INTEGRAL_MAX) {
        m->integral += (int32_t)err;
        if (m->integral > INTEGRAL_MAX)
            m->integral = INTEGRAL_MAX;
        if (m->integral < -INTEGRAL_MAX)
            m->integral = -INTEGRAL_MAX;
    }
    int32_t vref_q8 = m->plan.vel >> (PLANNER_SHIFT - 8);
    int64_t duty = ((int64_t)KFF * vref_q8) / 256 + (int64_t)KP * err +
                   /* cppcheck-suppress shiftNegativeLHS ; arithmetic right shift (docs/lint.md) */
                   ((int64_t)KD * (vref_q8 - m->vel_q8)) / 256 + (m->integral >> KI_SHIFT);
    if (m->plan.vel)
        duty += m->plan.vel > 0 ? KFRICTION : -KFRICTION;
    uint8_t limit = s->regs.mem[REG_CURRENT_LIMIT]; /* 0.1 A; 0 = no limit */
    if (limit) {
        int64_t emf = ((int64_t)KFF * m->vel_q8) / 256;
        int64_t band = ((int64_t)limit * s->board->duty_per_amp * 8) / 100;
        if (duty > emf + band)
            duty = emf + band;
        if (duty < emf - band)
            duty = emf - band;
    }
    if (duty > HAL_DUTY_MAX)
        duty = HAL_DUTY_MAX;
    if (duty < -HAL_DUTY_MAX)
        duty = -HAL_DUTY_MAX;
    return (int16_t)duty;
}

static void tick(struct servo *s)
{
    struct motion *m = &s->motion;
    measure(s);
    bool moving = m->mode != MOTION_OFF && m->mode != MOTION_HOLD;
    uint8_t ev = safety_tick(s, moving);
    if (ev == SAFETY_UNLOAD) {
        coast(s); /* torque off in the tick the fault is seen */
    } else if (ev == SAFETY_HEARTBEAT && moving &&
               !(m->mode == MOTION_HOME && m->home_phase == HOME_END)) {
        if (m->mode == MOTION_HOME)
            homing_fail(s);
        stop_soft(s); /* (returning onto the end is homing's own stop, §9 step 3) */
    }
    if (m->mode == MOTION_HOME && (s->safety.present & ERR_STALL)) {
        hold_here(s); /* a stall fails homing */
    }
    switch (m->mode) {
    case MOTION_STOP:
        planner_step_speed(&m->plan, 0, &m->lim);
        if (m->plan.vel == 0)
            m->mode = MOTION_HOLD;
        break;
    case MOTION_HOME:
        homing_tick(s);
        break;
    case MOTION_MOVE:
        if (planner_step_to(&m->plan, m->target, &m->lim))
            m->mode = MOTION_HOLD;
        break;
    case MOTION_SPEED:
        planner_step_speed(&m->plan, m->speed_target, &m->lim);
        break;
    case MOTION_TRAJ: {
        bool rest = planner_step_to(&m->plan, m->target, &m->lim);
        int64_t pt = (m->zero + units_to_counts(s, s->traj.pt[m->traj_next].angle)) * PLANNER_ONE;
        bool passed = m->plan.vel > 0 ? m->plan.pos >= pt : m->plan.vel < 0 ? m->plan.pos <= pt : rest;
        if (passed && m->traj_next < m->traj_stop) {
            m->traj_next++; /* through it without stopping: next point's speed */
            set_limits(s, s->traj.pt[m->traj_next].speed);
        } else if (rest) {
            if (m->traj_stop + 1u >= s->traj.count) {
                m->mode = MOTION_HOLD;
            } else {
                m->traj_next = (uint8_t)(m->traj_stop + 1u);
                traj_segment(s);
            }
        }
        break;
    }
    default:
        break;
    }
    if (m->mode == MOTION_OFF) {
        m->duty = 0;
    } else {
        m->duty = control(s, m);
        hal_motor_drive(s->hal, (int16_t)(m->duty * m->sign));
    }
}

/* Present-state registers (§5.1), each 16-bit one a single store. */
static void report(struct servo *s)
{
    struct motion *m = &s->motion;
    uint16_t pos = (uint16_t)present_units(s);
    if (regs_applicable(s->board, REG_PRESENT_POSITION))
        regs_set(&s->regs, REG_PRESENT_POSITION, pos);
    else
        regs_set(&s->regs, REG_TURNED_ANGLE, pos);
    int64_t num = (int64_t)m->vel_q8 * TICKS_PER_S * 3600;
    int64_t den = (int64_t)256 * resolution(s) * cpr(s);
    int64_t speed = (num + (num >= 0 ? den / 2 : -den / 2)) / den;
    if (speed > INT16_MAX)
        speed = INT16_MAX;
    if (speed < INT16_MIN)
        speed = INT16_MIN;
    regs_set(&s->regs, REG_PRESENT_SPEED, (uint16_t)(int16_t)speed);
    s->regs.mem[REG_MOVING] = (uint8_t)(m->mode != MOTION_OFF && m->mode != MOTION_HOLD);
    int16_t dc = hal_temperature_dc(s->hal); /* 0.1 C; register 46: bit 7 sign, 0-6 C */
    uint32_t deg = ((uint32_t)(dc < 0 ? -dc : dc) + 5u) / 10u;
    s->regs.mem[REG_PRESENT_TEMPERATURE] =
        (uint8_t)((deg > 127u ? 127u : deg) | (dc < 0 && deg ? 0x80u : 0u));
}

void motion_poll(struct servo *s, uint32_t now_us)
{
    struct motion *m = &s->motion;
    if ((int32_t)(now_us - m->tick_us) < (int32_t)MOTION_TICK_US)
        return;
    /* One tick per call. If the loop was held up (a flash compaction) the missed ticks
     * are dropped, not replayed back to back: ticks run at the same instant would see
     * all the motion in the first and none in the rest. */
    m->tick_us += MOTION_TICK_US;
    if ((int32_t)(now_us - m->tick_us) >= (int32_t)MOTION_TICK_US)
        m->tick_us = now_us;
    tick(s);
    report(s);
}
