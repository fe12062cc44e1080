/* motion_none.c - the motion layer of a servo without a motion engine yet: register
 * writes are stored and nothing moves; motion instructions are refused with an
 * instruction error, which PROTOCOL.md permits for what a servo cannot do. The motion
 * engine (issue 5) replaces this file. */
#include "motion.h"
#include "proto.h"
#include "servo.h"

void motion_init(struct servo *s)
{
    /* Rule 1: nothing to move to. With no sensor yet the present position is 0. */
    regs_set(&s->regs, REG_GOAL_POSITION, regs_present_position(&s->regs));
}

bool motion_write_allowed(const struct servo *s, uint8_t addr, uint8_t n)
{
    (void)s;
    (void)addr;
    (void)n;
    return true;
}

void motion_on_write(struct servo *s, uint8_t addr, uint8_t n)
{
    (void)s;
    (void)addr;
    (void)n;
}

uint8_t motion_start_end(struct servo *s, uint8_t what)
{
    (void)s;
    (void)what;
    return ERR_INSTRUCTION;
}

uint8_t motion_traj_action(struct servo *s)
{
    (void)s;
    return ERR_INSTRUCTION;
}

uint8_t motion_custom_move(struct servo *s, const struct custom_move *m)
{
    (void)s;
    (void)m;
    return ERR_INSTRUCTION;
}

void motion_reset(struct servo *s)
{
    (void)s;
}
