/* motion.c - the modes of the motor side (PROTOCOL.md §6, §9) and the control tick:
 * measure (control.c), protect (safety.c), step the mode (homing.c, sequence.c, the
 * planner), drive (control.c), report (present.c). What a host command means is
 * command.c's job; it starts modes through motion_mode.h.
 *
 * The three rules of §0: at power-up the motor is off and the goal equals the present
 * position; a speed of 0 drops the drive to zero in the tick it arrives and the brake
 * freezes the reference where the shaft is; releasing the brake or waking starts
 * nothing. Everything runs in the main loop. */
#include "hal.h"
#include "motion.h"
#include "motion_mode.h"
#include "present.h"
#include "proto.h"
#include "safety.h"
#include "servo.h"

#define HOMING_DEFAULT_ACC 36u /* 360 degree/s^2 when the ramp registers say "no ramp" */

struct scale motion_scale(const struct servo *s)
{
    return (struct scale){servo_board(s)->counts_per_rev, s->regs.mem[REG_RESOLUTION]};
}

void motion_set_limits(struct servo *s, uint16_t speed)
{
    struct motion *m = &s->motion;
    m->cruise = speed;
    m->lim.vmax = scale_speed_q24(motion_scale(s), speed & PROTO_SPEED_MAGNITUDE);
    if (m->lim.vmax < 1)
        m->lim.vmax = 1;
    uint8_t a = regs_ramp_addr(servo_board(s));
    m->lim.acc = scale_accel_q24(servo_board(s)->counts_per_rev, s->regs.mem[a], m->lim.vmax);
    m->lim.dec = scale_accel_q24(servo_board(s)->counts_per_rev, s->regs.mem[a + 1u], m->lim.vmax);
}

/* Counts x 2^24 to position units from the zero, and back. */
static int32_t q24_to_units(const struct servo *s, int64_t q24)
{
    return scale_counts_to_units(motion_scale(s), (q24 >> PLANNER_SHIFT) - s->motion.zero);
}

static int64_t units_to_q24(const struct servo *s, int32_t units)
{
    return (s->motion.zero + scale_units_to_counts(motion_scale(s), units)) * PLANNER_ONE;
}

void motion_rest_span(const struct servo *s, int32_t *lo, int32_t *hi)
{
    const struct motion *m = &s->motion;
    if (m->mode != MOTION_HOLD) {
        *lo = motion_present_units(s);
        *hi = *lo;
        return;
    }
    const int64_t band = (int64_t)CONTROL_HOLD_BAND << PLANNER_SHIFT; /* in Q24 */
    *lo = q24_to_units(s, m->plan.pos - band);
    *hi = q24_to_units(s, m->plan.pos + band);
}

/* The present position in units, as registers 36 and 40 report it. */
int32_t motion_present_units(const struct servo *s)
{
    return q24_to_units(s, s->motion.ctl.counts * PLANNER_ONE);
}

bool motion_may_start(const struct servo *s)
{
    return !s->regs.mem[REG_BRAKE] && !s->regs.mem[REG_SLEEP] && !safety_unloaded(&s->safety);
}

/* Register 49 (§5.1): a motor with photo switches moves only after homing, except in
 * speed mode when register 49 allows it. */
bool motion_referenced_for(const struct servo *s, bool speed_mode)
{
    return !servo_board(s)->photo_switches || s->motion.referenced ||
           (speed_mode && s->regs.mem[REG_MOVE_WITHOUT_REFERENCE]);
}

/* Homing is over: status nibble of register 24, the written nibble kept. */
static void motion_home_status(struct servo *s, uint8_t status)
{
    regs_set(&s->regs, REG_HOMING,
             (uint8_t)(((uint32_t)status << 4) | (s->regs.mem[REG_HOMING] & 0x0Fu)));
}

static void motion_home_fail(struct servo *s)
{
    s->motion.referenced = 0;
    motion_home_status(s, HOMING_STATUS_FAILED);
}

/* Start driving from wherever the shaft is, without a jump in velocity. */
void motion_engage(struct servo *s)
{
    struct motion *m = &s->motion;
    if (m->mode == MOTION_OFF) {
        m->plan.pos = m->ctl.counts * PLANNER_ONE;
        m->plan.vel = (int32_t)((int64_t)m->ctl.vel_q8 * (PLANNER_ONE >> 8));
        control_engage(&m->ctl);
        hal_motor_enable(s->hal, true);
    }
}

/* Torque off at once (speed 0, sleep, RESET). */
void motion_coast(struct servo *s)
{
    struct motion *m = &s->motion;
    if (m->mode == MOTION_HOME)
        motion_home_fail(s); /* aborted */
    m->mode = MOTION_OFF;
    control_release(&m->ctl);
    m->plan.vel = 0;
    hal_motor_drive(s->hal, 0);
    hal_motor_enable(s->hal, false);
}

/* In position mode the goal register reads where the motor heads or what it holds
 * (after a move ends, a cancel, a stop), clamped to the limits (§5.4: CW <= goal <= CCW
 * whenever it is read). Speed mode keeps the goal as written (the base's is relative). */
static void goal_follows(struct servo *s, int64_t q24)
{
    struct regs *r = &s->regs;
    if (regs_speed_mode(r))
        return;
    int32_t u = q24_to_units(s, q24);
    regs_set(r, REG_GOAL_POSITION, regs_clamp_goal(r, (uint16_t)(u < 0 ? 0 : u > 0xFFFF ? 0xFFFF : u)));
}

/* The reference rests: hold it, and the goal reads it. */
static void hold_reached(struct servo *s)
{
    s->motion.mode = MOTION_HOLD;
    goal_follows(s, s->motion.plan.pos);
}

/* Stop at once and hold where the shaft is (brake, resolution change). */
void motion_hold_here(struct servo *s)
{
    struct motion *m = &s->motion;
    if (m->mode == MOTION_HOME)
        motion_home_fail(s); /* aborted */
    if (m->mode == MOTION_OFF)
        return;
    m->plan.pos = m->ctl.counts * PLANNER_ONE;
    m->plan.vel = 0;
    hold_reached(s);
}

/* Brake (§6.3): stop at once and hold with torque, from any state, coasting included
 * (not while asleep or unloaded: torque stays off then). */
void motion_brake_hold(struct servo *s)
{
    if (s->motion.mode == MOTION_OFF && !s->regs.mem[REG_SLEEP] && !safety_unloaded(&s->safety)) {
        motion_engage(s);
        s->motion.mode = MOTION_HOLD;
    }
    motion_hold_here(s);
}

/* Ramp down with the deceleration, then hold: still (the heartbeat, §7.1), or within the
 * limits (a trajectory replaced, a motion that may not go on). */
static void stop_soft(struct servo *s, bool within)
{
    struct motion *m = &s->motion;
    if (m->mode != MOTION_OFF && m->mode != MOTION_HOLD) {
        m->mode = MOTION_STOP;
        m->stop_within = within;
    }
}

void motion_stop_soft(struct servo *s)
{
    stop_soft(s, true);
}

void motion_start_homing(struct servo *s)
{
    struct motion *m = &s->motion;
    motion_home_status(s, HOMING_STATUS_RUNNING);
    m->referenced = 0;
    if (!servo_board(s)->photo_switches || !motion_may_start(s)) {
        motion_home_fail(s);
        return;
    }
    motion_engage(s);
    m->mode = MOTION_HOME;
    uint32_t cpr = servo_board(s)->counts_per_rev;
    /* Divided unsigned, as every 64-bit division of the image (scale.c, div_round). */
    homing_start(&m->home, m->ctl.switches, m->ctl.counts,
                 (int64_t)((uint64_t)servo_board(s)->homing_travel_deg * cpr / 360u));
    m->lim.vmax = scale_dps_q24(cpr, servo_board(s)->homing_dps);
    uint8_t a = regs_ramp_addr(servo_board(s));
    uint8_t acc = s->regs.mem[a], dec = s->regs.mem[a + 1u];
    m->lim.acc = scale_accel_q24(cpr, acc ? acc : HOMING_DEFAULT_ACC, m->lim.vmax);
    m->lim.dec = scale_accel_q24(cpr, dec ? dec : HOMING_DEFAULT_ACC, m->lim.vmax);
    m->speed_target = homing_dir(&m->home) * m->lim.vmax;
}

/* Switch 2 found at the switch edge: the travel is measured; the limits are set (and
 * stored at the end of the pass); from the next tick homing returns onto the end. False
 * if the travel is out of range: homing failed. */
static bool motion_home_end(struct servo *s)
{
    struct motion *m = &s->motion;
    /* The end as the position reads wherever the shaft settles on the edge (a count
     * either side of the hold): within the limits it sets, at any resolution. */
    int32_t end = q24_to_units(s, (m->ctl.sw_edge + CONTROL_HOLD_BAND) * PLANNER_ONE);
    if (end < 1 || end > PROTO_LIMIT_MAX) {
        motion_hold_here(s);
        return false;
    }
    regs_set(&s->regs, REG_CW_LIMIT, 0);
    regs_set(&s->regs, REG_CCW_LIMIT, (uint16_t)end);
    m->target = m->ctl.sw_edge * PLANNER_ONE; /* stop and hold at the end itself */
    regs_set(&s->regs, REG_GOAL_POSITION, (uint16_t)q24_to_units(s, m->target));
    return true;
}

/* Back onto the end: done, and referenced, once the reference rests there. */
static void motion_home_return(struct servo *s)
{
    struct motion *m = &s->motion;
    if (planner_step_to(&m->plan, m->target, &m->lim)) {
        m->referenced = 1;
        motion_home_status(s, HOMING_STATUS_DONE);
        m->mode = MOTION_HOLD;
    }
}

/* One tick of homing (§9), after the switches were read. */
static void motion_home_tick(struct servo *s)
{
    struct motion *m = &s->motion;
    switch (homing_step(&m->home, m->ctl.switches, m->ctl.counts)) {
    case HOMING_EVENT_FAIL:
        motion_hold_here(s);
        return;
    case HOMING_EVENT_END:
        if (!motion_home_end(s))
            return;
        break; /* this tick still at homing speed, as the overrun was measured */
    case HOMING_EVENT_RETURN:
        motion_home_return(s);
        return;
    case HOMING_EVENT_ZERO:
        m->zero = m->ctl.sw_edge; /* positions count up from here toward the end */
        break;
    default:
        break;
    }
    m->speed_target = homing_dir(&m->home) * m->lim.vmax;
    planner_step_speed(&m->plan, m->speed_target, &m->lim);
}

/* A move to an absolute position in units (already clamped), at speed. */
void motion_start_move(struct servo *s, int32_t units, uint16_t speed)
{
    struct motion *m = &s->motion;
    if (proto_speed_is_stop(speed) || !motion_may_start(s) || !motion_referenced_for(s, false))
        return; /* a goal with speed 0 (or braked, asleep) is stored, nothing moves */
    motion_engage(s);
    motion_set_limits(s, speed);
    m->target = units_to_q24(s, units);
    m->mode = MOTION_MOVE;
}

void motion_start_speed(struct servo *s, uint16_t speed)
{
    struct motion *m = &s->motion;
    if (proto_speed_is_stop(speed)) {
        motion_coast(s); /* rule 3; §6.2: a stop without torque */
        return;
    }
    if (!motion_may_start(s) || !motion_referenced_for(s, true))
        return;
    motion_engage(s);
    motion_set_limits(s, speed);
    m->speed_target = (speed & PROTO_SPEED_REVERSE) ? -m->lim.vmax : m->lim.vmax;
    m->mode = MOTION_SPEED;
}

uint8_t motion_mode(const struct servo *s)
{
    return s->motion.mode;
}

void motion_mirror(struct servo *s, int8_t sign)
{
    struct motion *m = &s->motion;
    if (m->ctl.sign == sign)
        return;
    motion_coast(s); /* the motor is mirrored from now on: the reference is gone */
    control_mirror(&m->ctl);
    m->zero = -m->zero;
    m->referenced = 0;
    motion_home_status(s, HOMING_STATUS_NEVER); /* register 24 no longer reads "done" */
}

void motion_homing_abort(struct servo *s)
{
    if (s->motion.mode == MOTION_HOME)
        motion_hold_here(s);
}

void motion_new_ramps(struct servo *s)
{
    /* Re-planned at the cruise speed in force (a trajectory point's, a CUSTOM MOVE's:
     * not register 32's); homing keeps its own. */
    if (s->motion.mode != MOTION_OFF && s->motion.mode != MOTION_HOME)
        motion_set_limits(s, s->motion.cruise);
}

void motion_zero_here(struct servo *s)
{
    struct motion *m = &s->motion;
    m->zero = m->ctl.counts;
    if (m->mode == MOTION_HOLD) { /* hold exactly the new 0, where the shaft is */
        m->plan.pos = m->ctl.counts * PLANNER_ONE;
        m->plan.vel = 0;
    }
}

void motion_forget_reference(struct servo *s)
{
    s->motion.zero = s->motion.ctl.counts;
    s->motion.referenced = 0;
}

/* Where the reference comes to rest braking now at the deceleration in force. */
static int64_t stop_point(const struct motion *m)
{
    int64_t d = planner_stop_distance(m->plan.vel < 0 ? -m->plan.vel : m->plan.vel, m->lim.dec);
    return m->plan.pos + (m->plan.vel < 0 ? -d : d);
}

void motion_limits_changed(struct servo *s)
{
    struct motion *m = &s->motion;
    struct regs *r = &s->regs;
    if (regs_speed_mode(r))
        return;
    regs_set(r, REG_GOAL_POSITION, regs_clamp_goal(r, regs_get(r, REG_GOAL_POSITION)));
    traj_clamp(&s->traj, r);
    int64_t at;
    switch (m->mode) {
    case MOTION_MOVE: /* past a limit, the planner brakes at the deceleration, comes back */
    case MOTION_TRAJ: /* (and its stored points are clamped above) */
        at = m->target;
        break;
    case MOTION_SPEED: /* speed mode left while turning (§6.2): it stops within them */
    case MOTION_STOP:
        at = stop_point(m);
        break;
    case MOTION_HOLD: /* held outside the new limits: back within, unless braked (§6.3) */
        if (r->mem[REG_BRAKE])
            return;
        at = m->plan.pos;
        break;
    default: /* torque off: the next motion command moves within them; homing sets them */
        return;
    }
    int32_t u = q24_to_units(s, at);
    int32_t lo = regs_get(r, REG_CW_LIMIT), hi = regs_get(r, REG_CCW_LIMIT);
    int32_t in = u < lo ? lo : u > hi ? hi : u;
    if (m->mode == MOTION_TRAJ) {
        m->target = units_to_q24(s, in);
        return;
    }
    if (m->mode == MOTION_HOLD) {
        /* Within as the position register reads it wherever the held shaft settles (a
         * count either side): START/END 2 and homing set a limit to where it holds. */
        int32_t rest_lo, rest_hi;
        motion_rest_span(s, &rest_lo, &rest_hi);
        if (rest_lo >= lo && rest_hi <= hi)
            return;
    }
    /* On at the cruise speed in force or, from a hold, the homing speed. */
    uint16_t cruise = (uint16_t)(m->mode == MOTION_HOLD ? 0u : m->cruise & PROTO_SPEED_MAGNITUDE);
    if (!cruise) {
        int32_t v = (int32_t)servo_board(s)->homing_dps * 10 / r->mem[REG_RESOLUTION];
        cruise = (uint16_t)(v < 1 ? 1 : v > (int32_t)PROTO_SPEED_MAGNITUDE ? (int32_t)PROTO_SPEED_MAGNITUDE : v);
    }
    motion_start_move(s, in, cruise);
    if (m->mode == MOTION_MOVE)
        goal_follows(s, m->target);
    else
        motion_stop_soft(s); /* it may not move on (register 49's speed mode, unhomed) */
}

/* Goal register written: absolute move, or on the base a move relative to the present
 * angle (§6.1). */
void motion_init(struct servo *s)
{
    struct motion *m = &s->motion;
    *m = (struct motion){0};
    control_init(&m->ctl, hal_motor_position(s->hal),
                 s->regs.mem[REG_HOMING_ZERO_SIDE] == 2u ? -1 : 1);
    m->tick_us = hal_clock_us(s->hal);
    motion_coast(s); /* rule 1: the motor is off until a command asks for motion */
    regs_set(&s->regs, REG_GOAL_POSITION, regs_present_position(&s->regs));
    /* Homing without switches never ends, and a move on the wrong sensor runs away: a
     * port without the board's fittings gets a servo that answers but never moves. */
    safety_unfit(&s->safety, (uint8_t)(servo_board(s)->fittings & ~hal_capabilities(s->hal)));
}

static struct sequence_frame seq_frame(const struct servo *s)
{
    return (struct sequence_frame){motion_scale(s), s->motion.zero};
}

void motion_start_traj(struct servo *s)
{
    struct motion *m = &s->motion;
    traj_clamp(&s->traj, &s->regs); /* points stored before the limits narrowed (§5.4) */
    motion_engage(s);
    m->mode = MOTION_TRAJ;
    struct sequence_frame f = seq_frame(s);
    sequence_start(&m->seq, &s->traj, &f, m->plan.pos, &m->target);
    motion_set_limits(s, sequence_speed(&m->seq, &s->traj));
}

static void traj_tick(struct servo *s)
{
    struct motion *m = &s->motion;
    bool rest = planner_step_to(&m->plan, m->target, &m->lim);
    struct sequence_frame f = seq_frame(s);
    switch (sequence_step(&m->seq, &s->traj, &f, &m->plan, rest, &m->target)) {
    case SEQ_NEW_SPEED:
    case SEQ_NEW_SEGMENT:
        motion_set_limits(s, sequence_speed(&m->seq, &s->traj));
        break;
    case SEQ_DONE:
        hold_reached(s);
        break;
    default:
        break;
    }
}

static bool is_moving(const struct motion *m)
{
    return m->mode != MOTION_OFF && m->mode != MOTION_HOLD;
}

/* Protection first: an unload drops the torque in the tick the fault is seen; the
 * heartbeat ramps a motion down (and fails a homing it interrupts). */
static void protect(struct servo *s)
{
    struct motion *m = &s->motion;
    const struct safety_inputs in = {
        .supply_mv = hal_supply_mv(s->hal),
        .temperature_dc = hal_temperature_dc(s->hal),
        .current_ma = hal_motor_current_ma(s->hal),
        .duty = m->ctl.duty,
        .vel_q8 = m->ctl.vel_q8,
        .moving = is_moving(m),
    };
    uint8_t ev = safety_tick(&s->safety, &s->regs, servo_board(s), &in);
    if (ev == SAFETY_UNLOAD) {
        motion_coast(s);
    } else if (ev == SAFETY_HEARTBEAT && in.moving &&
               !(m->mode == MOTION_HOME && homing_returning(&m->home))) {
        if (m->mode == MOTION_HOME)
            motion_home_fail(s);
        stop_soft(s, false); /* §7.1: it stops and holds still */
    }
    if (m->mode == MOTION_HOME && safety_stalled(&s->safety))
        motion_hold_here(s); /* a stall fails homing */
}

static void tick(struct servo *s)
{
    struct motion *m = &s->motion;
    control_measure(&m->ctl, hal_motor_position(s->hal), hal_photo_switches(s->hal));
    protect(s);
    switch (m->mode) {
    case MOTION_STOP:
        planner_step_speed(&m->plan, 0, &m->lim);
        if (m->plan.vel == 0) {
            hold_reached(s);
            if (m->stop_within)
                motion_limits_changed(s); /* back within them if it stopped outside */
        }
        break;
    case MOTION_HOME:
        motion_home_tick(s);
        break;
    case MOTION_MOVE:
        if (planner_step_to(&m->plan, m->target, &m->lim))
            hold_reached(s);
        break;
    case MOTION_SPEED:
        planner_step_speed(&m->plan, m->speed_target, &m->lim);
        break;
    case MOTION_TRAJ:
        traj_tick(s);
        break;
    default:
        break;
    }
    if (m->mode == MOTION_OFF) {
        control_release(&m->ctl);
    } else {
        const struct control_limits lim = {s->regs.mem[REG_CURRENT_LIMIT], servo_board(s)->duty_per_amp};
        hal_motor_drive(s->hal, (int16_t)(control_duty(&m->ctl, &m->plan, &lim) * m->ctl.sign));
    }
}

/* A function of its own under -flto too: hal/stm32f1/qemu_cost.py counts the control
 * tick from its entry. */
__attribute__((noinline)) void motion_poll(struct servo *s, uint32_t now_us)
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
    motion_report(s);
}

void motion_report(struct servo *s)
{
    const struct motion *m = &s->motion;
    /* Moving (§5.1 register 42, "1 while a motion runs"): a motion is commanded, or the
     * shaft still turns (coasting, braking, a restart on a turning shaft; the filter
     * reads exactly 0 once the count has rested), or it is still being brought onto the
     * position held. So moving 0 means the present position stays what it reads. */
    int64_t off = ((m->plan.pos + PLANNER_ONE / 2) >> PLANNER_SHIFT) - m->ctl.counts;
    bool settling = m->mode == MOTION_HOLD && (off > CONTROL_HOLD_BAND || off < -CONTROL_HOLD_BAND);
    const struct present_inputs p = {
        .position = motion_present_units(s),
        .speed = scale_speed_units(motion_scale(s), m->ctl.vel_q8),
        .moving = is_moving(m) || m->ctl.vel_q8 != 0 || settling,
        .switches = m->ctl.switches,
        .temperature_dc = hal_temperature_dc(s->hal),
    };
    present_write(&s->regs, servo_board(s), &p);
}
