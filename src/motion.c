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
    return (struct scale){s->board->counts_per_rev, s->regs.mem[REG_RESOLUTION]};
}

void motion_set_limits(struct servo *s, uint16_t speed)
{
    struct motion *m = &s->motion;
    m->cruise = speed;
    m->lim.vmax = scale_speed_q24(motion_scale(s), speed & PROTO_SPEED_MAGNITUDE);
    if (m->lim.vmax < 1)
        m->lim.vmax = 1;
    uint8_t a = regs_ramp_addr(s->board);
    m->lim.acc = scale_accel_q24(s->board->counts_per_rev, s->regs.mem[a], m->lim.vmax);
    m->lim.dec = scale_accel_q24(s->board->counts_per_rev, s->regs.mem[a + 1u], m->lim.vmax);
}

/* The present position in units, as registers 36 and 40 report it. */
int32_t motion_present_units(const struct servo *s)
{
    return scale_counts_to_units(motion_scale(s), s->motion.ctl.counts - s->motion.zero);
}

bool motion_may_start(const struct servo *s)
{
    return !s->regs.mem[REG_BRAKE] && !s->regs.mem[REG_SLEEP] && !safety_unloaded(&s->safety);
}

/* Register 49 (§5.1): a motor with photo switches moves only after homing, except in
 * speed mode when register 49 allows it. */
bool motion_referenced_for(const struct servo *s, bool speed_mode)
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
        homing_fail(s); /* aborted */
    m->mode = MOTION_OFF;
    control_release(&m->ctl);
    m->plan.vel = 0;
    hal_motor_drive(s->hal, 0);
    hal_motor_enable(s->hal, false);
}

/* Stop at once and hold where the shaft is (brake, resolution change). */
void motion_hold_here(struct servo *s)
{
    struct motion *m = &s->motion;
    if (m->mode == MOTION_HOME)
        homing_fail(s); /* aborted */
    if (m->mode == MOTION_OFF)
        return;
    m->plan.pos = m->ctl.counts * PLANNER_ONE;
    m->plan.vel = 0;
    m->mode = MOTION_HOLD;
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

/* Ramp down with the deceleration, then hold (heartbeat). */
static void stop_soft(struct servo *s)
{
    struct motion *m = &s->motion;
    if (m->mode != MOTION_OFF && m->mode != MOTION_HOLD)
        m->mode = MOTION_STOP;
}

void motion_start_homing(struct servo *s)
{
    struct motion *m = &s->motion;
    homing_status(s, HOMING_RUNNING);
    m->referenced = 0;
    if (!s->board->photo_switches || !motion_may_start(s)) {
        homing_fail(s);
        return;
    }
    motion_engage(s);
    m->mode = MOTION_HOME;
    uint32_t cpr = s->board->counts_per_rev;
    homing_start(&m->home, m->ctl.switches, m->ctl.counts,
                 (int64_t)s->board->homing_travel_deg * cpr / 360);
    m->lim.vmax = scale_dps_q24(cpr, s->board->homing_dps);
    uint8_t a = regs_ramp_addr(s->board);
    uint8_t acc = s->regs.mem[a], dec = s->regs.mem[a + 1u];
    m->lim.acc = scale_accel_q24(cpr, acc ? acc : HOMING_DEFAULT_ACC, m->lim.vmax);
    m->lim.dec = scale_accel_q24(cpr, dec ? dec : HOMING_DEFAULT_ACC, m->lim.vmax);
    m->speed_target = homing_dir(&m->home) * m->lim.vmax;
}

/* Switch 2 found at the switch edge: the travel is measured; the limits are set (and
 * stored at the end of the pass); from the next tick homing returns onto the end. False
 * if the travel is out of range: homing failed. */
static bool homing_end(struct servo *s)
{
    struct motion *m = &s->motion;
    int32_t end = scale_counts_to_units(motion_scale(s), m->ctl.sw_edge - m->zero);
    if (end < 1 || end > 0x7FFF) {
        motion_hold_here(s);
        return false;
    }
    regs_set(&s->regs, REG_CW_LIMIT, 0);
    regs_set(&s->regs, REG_CCW_LIMIT, (uint16_t)end);
    m->target = m->ctl.sw_edge * PLANNER_ONE; /* stop and hold at the end itself */
    regs_set(&s->regs, REG_GOAL_POSITION, (uint16_t)end);
    return true;
}

/* Back onto the end: done, and referenced, once the reference rests there. */
static void homing_return(struct servo *s)
{
    struct motion *m = &s->motion;
    if (planner_step_to(&m->plan, m->target, &m->lim)) {
        m->referenced = 1;
        homing_status(s, HOMING_DONE);
        m->mode = MOTION_HOLD;
    }
}

/* One tick of homing (§9), after the switches were read. */
static void homing_tick(struct servo *s)
{
    struct motion *m = &s->motion;
    switch (homing_step(&m->home, m->ctl.switches, m->ctl.counts)) {
    case HOMING_FAIL:
        motion_hold_here(s);
        return;
    case HOMING_END:
        if (!homing_end(s))
            return;
        break; /* this tick still at homing speed, as the overrun was measured */
    case HOMING_RETURN:
        homing_return(s);
        return;
    case HOMING_ZERO:
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
    m->target = (m->zero + scale_units_to_counts(motion_scale(s), units)) * PLANNER_ONE;
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
    m->speed_target = (speed & 0x8000u) ? -m->lim.vmax : m->lim.vmax;
    m->mode = MOTION_SPEED;
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
}

static struct sequence_frame seq_frame(const struct servo *s)
{
    return (struct sequence_frame){motion_scale(s), s->motion.zero};
}

void motion_start_traj(struct servo *s)
{
    struct motion *m = &s->motion;
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
        m->mode = MOTION_HOLD;
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
    uint8_t ev = safety_tick(&s->safety, &s->regs, s->board, &in);
    if (ev == SAFETY_UNLOAD) {
        motion_coast(s);
    } else if (ev == SAFETY_HEARTBEAT && in.moving &&
               !(m->mode == MOTION_HOME && homing_returning(&m->home))) {
        if (m->mode == MOTION_HOME)
            homing_fail(s);
        stop_soft(s);
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
    case MOTION_TRAJ:
        traj_tick(s);
        break;
    default:
        break;
    }
    if (m->mode == MOTION_OFF) {
        control_release(&m->ctl);
    } else {
        const struct control_limits lim = {s->regs.mem[REG_CURRENT_LIMIT], s->board->duty_per_amp};
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
    present_write(&s->regs, s->board, &p);
}
