/* command.c - what the host's commands mean to the motor side (PROTOCOL.md §4.6-§4.8,
 * §5, §6): register writes that move, stop, brake, sleep, home or mirror the motor, START/
 * END, TRAJECTORY ACTION, CUSTOM MOVE and RESET, each turned into a mode of motion.c.
 * Rule 3 of §0 lives here: a speed of 0 is never refused and drops the torque at once.
 * Main loop only. */
#include "motion.h"
#include "motion_mode.h"
#include "proto.h"
#include "safety.h"
#include "servo.h"

static void goal_written(struct servo *s)
{
    uint16_t goal = regs_get(&s->regs, REG_GOAL_POSITION);
    uint16_t speed = regs_get(&s->regs, REG_MOVING_SPEED);
    if (s->board->variant == VARIANT_BASE)
        motion_start_move(s, motion_present_units(s) + (int16_t)goal, speed);
    else if (!regs_speed_mode(&s->regs))
        motion_start_move(s, goal, speed);
}

static void speed_written(struct servo *s)
{
    struct motion *m = &s->motion;
    uint16_t speed = regs_get(&s->regs, REG_MOVING_SPEED);
    if (proto_speed_is_stop(speed)) {
        motion_coast(s);
    } else if (regs_speed_mode(&s->regs) && m->mode != MOTION_MOVE) {
        motion_start_speed(s, speed);
    } else if (m->mode == MOTION_MOVE || m->mode == MOTION_TRAJ) {
        motion_set_limits(s, speed); /* a new cruise speed, re-planned from here */
    }
}

static bool touches(uint8_t addr, uint8_t n, uint8_t reg)
{
    return reg >= addr && reg < addr + n;
}

bool motion_write_allowed(const struct servo *s, uint8_t addr, const uint8_t *data, uint8_t n)
{
    const struct safety *sf = &s->safety;
    if (touches(addr, n, REG_CLEAR_UNLOAD) && !safety_may_clear(sf))
        return false; /* the condition is still there */
    bool unloaded = safety_unloaded(sf) && !touches(addr, n, REG_CLEAR_UNLOAD);
    if (touches(addr, n, REG_HOMING) && data[REG_HOMING - addr] == 1u && unloaded)
        return false;
    if (touches(addr, n, REG_GOAL_POSITION) &&
        (unloaded || !motion_referenced_for(s, false)))
        return false;
    if ((touches(addr, n, REG_CW_LIMIT) || touches(addr, n, REG_CCW_LIMIT)) &&
        s->motion.mode == MOTION_HOME)
        return false; /* homing measures the limits: they are its own until it ends */
    if (touches(addr, n, REG_MOVING_SPEED)) {
        uint8_t i = (uint8_t)(REG_MOVING_SPEED - addr);
        bool stop = proto_speed_is_stop(proto_get16(&data[i])); /* rule 3: never refused */
        /* In position mode the speed only sets the cruise speed: it starts nothing. */
        if (!stop && regs_speed_mode(&s->regs) && (unloaded || !motion_referenced_for(s, true)))
            return false;
    }
    return true;
}

/* A function of its own under -flto too: hal/stm32f1/qemu_cost.py counts a re-plan
 * from its entry. */
__attribute__((noinline)) void motion_on_write(struct servo *s, uint8_t addr, uint8_t n)
{
    struct motion *m = &s->motion;
    if (touches(addr, n, REG_CLEAR_UNLOAD))
        safety_clear(&s->safety); /* nothing moves until the next motion command */
    if (touches(addr, n, REG_HOMING_ZERO_SIDE) &&
        m->ctl.sign != (s->regs.mem[REG_HOMING_ZERO_SIDE] == 2u ? -1 : 1)) {
        motion_coast(s); /* the motor is mirrored from now on: the reference is gone */
        control_mirror(&m->ctl);
        m->zero = -m->zero;
        m->referenced = 0;
    }
    if (touches(addr, n, REG_HOMING)) {
        if (s->regs.mem[REG_HOMING] & 0x0Fu)
            motion_start_homing(s);
        else if (m->mode == MOTION_HOME)
            motion_hold_here(s); /* writing 0 aborts */
    }
    if (touches(addr, n, REG_SLEEP) && s->regs.mem[REG_SLEEP])
        motion_coast(s);
    if (touches(addr, n, REG_BRAKE) && s->regs.mem[REG_BRAKE])
        motion_brake_hold(s);
    if (touches(addr, n, REG_RESOLUTION)) {
        motion_hold_here(s); /* §5: a resolution change stops any motion */
        return;
    }
    uint8_t a = regs_ramp_addr(s->board);
    /* New ramps, re-planned at the cruise speed in force (a trajectory point's, a CUSTOM
     * MOVE's: not register 32's); homing keeps its own. */
    if ((touches(addr, n, a) || touches(addr, n, (uint8_t)(a + 1u))) && m->mode != MOTION_OFF &&
        m->mode != MOTION_HOME)
        motion_set_limits(s, m->cruise);
    if (touches(addr, n, REG_GOAL_POSITION))
        goal_written(s);
    else if (touches(addr, n, REG_MOVING_SPEED))
        speed_written(s);
}

uint8_t motion_start_end(struct servo *s, uint8_t what)
{
    struct motion *m = &s->motion;
    if (m->mode == MOTION_HOME)
        return ERR_INSTRUCTION; /* homing sets the zero and the limits itself */
    if (what == 1u) {
        m->zero = m->ctl.counts; /* the present position becomes 0 */
        m->plan.pos = m->ctl.counts * PLANNER_ONE;
        m->target = m->plan.pos;
        regs_set(&s->regs, REG_CW_LIMIT, 0);
    } else {
        int32_t here = motion_present_units(s);
        if (here < (int32_t)regs_get(&s->regs, REG_CW_LIMIT) || here > 0x7FFF)
            return ERR_INSTRUCTION;
        regs_set(&s->regs, REG_CCW_LIMIT, (uint16_t)here);
    }
    return 0; /* both are stored (§4.6): the main loop syncs the store after the frame */
}

uint8_t motion_traj_action(struct servo *s)
{
    if (!motion_may_start(s) || !motion_referenced_for(s, false))
        return ERR_INSTRUCTION;
    motion_start_traj(s);
    return 0;
}

uint8_t motion_custom_allowed(const struct servo *s, const struct custom_move *cm)
{
    if (proto_speed_is_stop(cm->speed))
        return 0; /* rule 3: a speed of 0 always stops */
    return motion_may_start(s) && motion_referenced_for(s, false) ? 0u : ERR_INSTRUCTION;
}

void motion_custom_move(struct servo *s, const struct custom_move *cm)
{
    if (proto_speed_is_stop(cm->speed)) {
        motion_coast(s);
        return;
    }
    int32_t target;
    if (cm->absolute) {
        target = regs_clamp_goal(&s->regs, cm->target);
    } else {
        int32_t rel = (cm->speed & 0x8000u) ? -(int32_t)cm->target : (int32_t)cm->target;
        target = motion_present_units(s) + rel;
        if (!regs_speed_mode(&s->regs))
            target = regs_clamp_goal(&s->regs, (uint16_t)(target < 0 ? 0 : target > 0xFFFF
                                                                                ? 0xFFFF
                                                                                : target));
    }
    motion_start_move(s, target, (uint16_t)(cm->speed & PROTO_SPEED_MAGNITUDE));
}

void motion_torque_off(struct servo *s)
{
    motion_coast(s);
}

void motion_reset(struct servo *s)
{
    motion_coast(s);
    s->motion.zero = s->motion.ctl.counts;
    s->motion.referenced = 0; /* §4.5: RESET clears the homing reference */
}


int32_t motion_position(const struct servo *s)
{
    return motion_present_units(s);
}
