/* motion_mode.h - the modes of the motion layer (motion.c), for the command layer
 * (command.c) only: the rest of the firmware sees include/motion.h. */
#ifndef MOTION_MODE_H
#define MOTION_MODE_H

#include <stdbool.h>
#include <stdint.h>

#include "scale.h"

struct servo;

struct scale motion_scale(const struct servo *s);
int32_t motion_present_units(const struct servo *s); /* registers 36 and 40 */

/* What the present position reads, lowest and highest, wherever a held shaft settles
 * (within CONTROL_HOLD_BAND of the hold); the present position when not holding. */
void motion_rest_span(const struct servo *s, int32_t *lo, int32_t *hi);

/* The ramps of the ramp registers at a moving-speed register value (bit 15 ignored). */
void motion_set_limits(struct servo *s, uint16_t speed);

/* Not braked, asleep or unloaded. */
bool motion_may_start(const struct servo *s);

/* Register 49 (§5.1): a motor with photo switches moves only after homing, except in
 * speed mode when register 49 allows it. */
bool motion_referenced_for(const struct servo *s, bool speed_mode);

uint8_t motion_mode(const struct servo *s); /* enum motion_mode */

void motion_engage(struct servo *s);     /* drive from where the shaft is, no jump */
void motion_coast(struct servo *s);      /* torque off at once */
void motion_hold_here(struct servo *s);  /* stop at once, hold where the shaft is */
void motion_brake_hold(struct servo *s); /* §6.3, from any state, coasting included */
void motion_start_homing(struct servo *s);
void motion_start_move(struct servo *s, int32_t units, uint16_t speed); /* absolute, clamped */
void motion_start_speed(struct servo *s, uint16_t speed);
void motion_start_traj(struct servo *s);
void motion_stop_soft(struct servo *s);  /* ramp down at the deceleration, hold within */
void motion_mirror(struct servo *s, int8_t sign); /* register 19: coast, mirrored, unhomed */
void motion_homing_abort(struct servo *s);  /* register 24 = 0: stop homing, hold */
void motion_new_ramps(struct servo *s);     /* re-plan at the cruise speed in force */
void motion_zero_here(struct servo *s);     /* START/END 1: the present position is 0 */
void motion_forget_reference(struct servo *s); /* RESET */

/* The angle limits (or the zero they count from) changed: the goal register, a running
 * move's target, a trajectory's points are clamped to them; a motor turning in speed mode
 * that now has limits stops with its deceleration within them; a shaft held outside them
 * comes back (at the cruise speed in force, or the homing speed), unless braked. */
void motion_limits_changed(struct servo *s);

#endif
