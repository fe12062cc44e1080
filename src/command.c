/* command.c - what the host's commands mean to the motor (command.h): register writes
 * that move, stop, brake, sleep, home, rescale or mirror the motor or change its limits,
 * START/END, TRAJECTORY ACTION, CUSTOM MOVE and RESET, each turned into a mode of
 * motion.c through motion_mode.h. It keeps no state of its own and never touches the
 * motion layer's. Rule 3 of §0 lives here: a speed of 0 is never refused and drops the
 * torque at once. Main loop only. */
#include <stddef.h>

#include "command.h"
#include "motion_mode.h"
#include "proto.h"
#include "safety.h"
#include "servo.h"

bool command_may_move(const struct servo *s)
{
    return motion_may_start(s) && motion_referenced_for(s, false);
}

static void goal_written(struct servo *s)
{
    uint16_t goal = regs_get(&s->regs, REG_GOAL_POSITION);
    uint16_t speed = regs_get(&s->regs, REG_MOVING_SPEED);
    if (servo_board(s)->variant == VARIANT_BASE)
        motion_start_move(s, motion_present_units(s) + (int16_t)goal, speed);
    else if (!regs_speed_mode(&s->regs))
        motion_start_move(s, goal, speed);
}

static void speed_written(struct servo *s)
{
    uint16_t speed = regs_get(&s->regs, REG_MOVING_SPEED);
    uint8_t mode = motion_mode(s);
    if (proto_speed_is_stop(speed))
        motion_coast(s);
    else if (regs_speed_mode(&s->regs) && mode != MOTION_MOVE)
        motion_start_speed(s, speed);
    else if (mode == MOTION_MOVE || mode == MOTION_TRAJ)
        motion_set_limits(s, speed); /* a new cruise speed, re-planned from here */
}

uint8_t command_write_check(const struct servo *s, const struct reg_write *w)
{
    bool unloaded = safety_unloaded(&s->safety) && !reg_write_touches(w, REG_CLEAR_UNLOAD);
    if (reg_write_touches(w, REG_HOMING) && w->data[REG_HOMING - w->addr] == 1u && unloaded)
        return ERR_INSTRUCTION;
    if (reg_write_touches(w, REG_GOAL_POSITION) && (unloaded || !motion_referenced_for(s, false)))
        return ERR_INSTRUCTION;
    if ((reg_write_touches(w, REG_CW_LIMIT) || reg_write_touches(w, REG_CCW_LIMIT)) &&
        motion_mode(s) == MOTION_HOME)
        return ERR_INSTRUCTION; /* homing measures the limits: they are its own until it ends */
    if (reg_write_touches(w, REG_MOVING_SPEED)) {
        bool stop = proto_speed_is_stop(proto_get16(&w->data[REG_MOVING_SPEED - w->addr]));
        /* Rule 3: a stop is never refused. In position mode the speed only sets the cruise
         * speed: it starts nothing. In speed mode it would start turning: not while homing
         * runs (its motion is its own until it ends, as its limits are; taking it over left
         * register 24 reading "running" for ever). */
        if (!stop && regs_speed_mode(&s->regs) &&
            (unloaded || motion_mode(s) == MOTION_HOME || !motion_referenced_for(s, true)))
            return ERR_INSTRUCTION;
    }
    return 0;
}

/* Register 13 changed (§5): limits and goal keep meaning the same angles (rounded), the
 * trajectory is dropped, and the motor stops and holds. */
static void resolution_written(struct servo *s, uint8_t old_res)
{
    struct regs *r = &s->regs;
    uint8_t new_res = r->mem[REG_RESOLUTION];
    uint16_t was = regs_present_position(r); /* still in the old unit */
    bool joint = !regs_speed_mode(r);
    bool inside = joint && was >= regs_get(r, REG_CW_LIMIT) && was <= regs_get(r, REG_CCW_LIMIT);
    static const uint8_t rescaled[] = {REG_CW_LIMIT, REG_CCW_LIMIT, REG_GOAL_POSITION};
    for (size_t i = 0; i < sizeof rescaled; i++) {
        uint8_t a = rescaled[i];
        uint32_t v = ((uint32_t)regs_get(r, a) * old_res + new_res / 2u) / new_res;
        regs_set(r, a, (uint16_t)(v > regs_max(&regs_table[a]) ? regs_max(&regs_table[a]) : v));
    }
    /* Rounding never makes a joint a wheel: both limits 0 is speed mode (§6.2), entered
     * only by writing 0 to both; a CCW limit of a few degrees rounded to 0 at a coarse
     * resolution keeps one unit. */
    if (joint && regs_get(r, REG_CCW_LIMIT) == 0u)
        regs_set(r, REG_CCW_LIMIT, 1);
    traj_clear(&s->traj);
    /* A shaft within its limits stays within them: a limit rounds to the nearest new
     * unit, and the position, which nothing moves, may round the other way (homing holds
     * on the switch edge, up to half a unit past the limit it measured). The limit then
     * widens by that unit rather than the servo moving on its own. */
    int32_t lo, hi;
    motion_rest_span(s, &lo, &hi);
    if (inside && lo >= 0 && hi <= PROTO_LIMIT_MAX) {
        if (hi > (int32_t)regs_get(r, REG_CCW_LIMIT))
            regs_set(r, REG_CCW_LIMIT, (uint16_t)hi);
        if (lo < (int32_t)regs_get(r, REG_CW_LIMIT))
            regs_set(r, REG_CW_LIMIT, (uint16_t)lo);
    }
    /* A motion running is cancelled where the shaft is (the goal then reads what it
     * holds); at rest, the goal keeps meaning the same angle, as the limits do. */
    uint8_t mode = motion_mode(s);
    if (mode != MOTION_OFF && mode != MOTION_HOLD)
        motion_hold_here(s);
    motion_limits_changed(s);
}

/* A function of its own under -flto too: hal/stm32f1/qemu_cost.py counts a re-plan
 * from its entry. */
__attribute__((noinline)) void command_written(struct servo *s, const struct reg_write *w)
{
    const struct regs *r = &s->regs;
    if (reg_write_touches(w, REG_HOMING_ZERO_SIDE))
        motion_mirror(s, r->mem[REG_HOMING_ZERO_SIDE] == 2u ? -1 : 1);
    if (reg_write_touches(w, REG_HOMING)) {
        if (r->mem[REG_HOMING] & 0x0Fu)
            motion_start_homing(s);
        else
            motion_homing_abort(s); /* writing 0 aborts */
    }
    if (reg_write_touches(w, REG_SLEEP) && r->mem[REG_SLEEP])
        motion_coast(s);
    if (reg_write_touches(w, REG_BRAKE) && r->mem[REG_BRAKE])
        motion_brake_hold(s);
    if (reg_write_touches(w, REG_RESOLUTION) &&
        r->mem[REG_RESOLUTION] != w->old_resolution) {
        resolution_written(s, w->old_resolution); /* §5: changing 13 stops motion */
        return;
    }
    if (reg_write_touches(w, REG_CW_LIMIT) || reg_write_touches(w, REG_CCW_LIMIT))
        motion_limits_changed(s);
    uint8_t a = regs_ramp_addr(servo_board(s));
    if (reg_write_touches(w, a) || reg_write_touches(w, (uint8_t)(a + 1u)))
        motion_new_ramps(s);
    if (reg_write_touches(w, REG_GOAL_POSITION))
        goal_written(s);
    else if (reg_write_touches(w, REG_MOVING_SPEED))
        speed_written(s);
}

uint8_t command_start_end(struct servo *s, uint8_t what)
{
    struct regs *r = &s->regs;
    if (motion_mode(s) == MOTION_HOME)
        return ERR_INSTRUCTION; /* homing sets the zero and the limits itself */
    if (what == 1u) {
        /* A trajectory running ends, as at a TRAJECTORY WRITE: the points after the
         * segment running would be taken from the new zero, a path neither the stored
         * one nor that one moved. */
        if (motion_mode(s) == MOTION_TRAJ)
            motion_stop_soft(s);
        motion_zero_here(s); /* the present position becomes 0 */
        regs_set(r, REG_CW_LIMIT, 0);
    } else {
        int32_t lo, here; /* the highest a held shaft reads where it settles */
        motion_rest_span(s, &lo, &here);
        if (here < (int32_t)regs_get(r, REG_CW_LIMIT) || here > PROTO_LIMIT_MAX)
            return ERR_INSTRUCTION;
        if (here == 0 && regs_get(r, REG_CW_LIMIT) == 0u)
            return ERR_INSTRUCTION; /* both limits 0 would make the joint a wheel (§6.2) */
        regs_set(r, REG_CCW_LIMIT, (uint16_t)here);
    }
    motion_limits_changed(s);
    return 0; /* both are stored (§4.6): the main loop syncs the store after the frame */
}

void command_traj_action(struct servo *s)
{
    motion_start_traj(s);
}

void command_traj_written(struct servo *s)
{
    if (motion_mode(s) == MOTION_TRAJ)
        motion_stop_soft(s);
}

void command_custom_move(struct servo *s, const struct custom_move *cm)
{
    if (proto_speed_is_stop(cm->speed)) {
        motion_coast(s); /* rule 3: a speed of 0 always stops */
        return;
    }
    if (cm->has_ramps) {
        /* §4.8: written into the ramp registers; on the base they are EEPROM, kept lazily
         * so that driving never spends the commit budget (docs/persistence.md). */
        uint8_t a = regs_ramp_addr(servo_board(s));
        regs_set_lazy(&s->regs, a, cm->acc);
        regs_set_lazy(&s->regs, (uint8_t)(a + 1u), cm->dec);
    }
    int32_t target;
    if (cm->absolute) {
        target = regs_clamp_goal(&s->regs, cm->target);
    } else {
        int32_t rel = (cm->speed & PROTO_SPEED_REVERSE) ? -(int32_t)cm->target : (int32_t)cm->target;
        target = motion_present_units(s) + rel;
        if (!regs_speed_mode(&s->regs))
            target = regs_clamp_goal(&s->regs, (uint16_t)(target < 0 ? 0 : target > 0xFFFF
                                                                                ? 0xFFFF
                                                                                : target));
    }
    motion_start_move(s, target, (uint16_t)(cm->speed & PROTO_SPEED_MAGNITUDE));
}

void command_coast(struct servo *s)
{
    motion_coast(s);
}

void command_reset(struct servo *s)
{
    motion_coast(s);
    motion_forget_reference(s); /* §4.5: RESET clears the homing reference */
}
