/* planner.h - time-optimal trapezoidal motion reference, evaluated once per control tick
 * (PROTOCOL.md §6). It re-plans from its present position and velocity every tick, so a
 * new goal, speed or ramp takes effect at once with position and velocity continuous:
 * it accelerates, cruises and brakes along the exact discrete braking curve to land on
 * the goal with zero error; it brakes first when it runs faster than the new limit; a
 * goal inside the stopping distance is overshot at the deceleration limit and then
 * approached again, landing exactly.
 *
 * Fixed point: positions are encoder counts x 2^24 (int64), velocities counts per tick
 * x 2^24, accelerations counts per tick^2 x 2^24 (int32). Pure integer code. */
#ifndef PLANNER_H
#define PLANNER_H

#include <stdbool.h>
#include <stdint.h>

#define PLANNER_SHIFT 24
#define PLANNER_ONE ((int64_t)1 << PLANNER_SHIFT) /* one count */

struct plan {
    int64_t pos; /* reference position */
    int32_t vel; /* reference velocity: what pos moved by in the last tick */
};

/* Limits of a move: cruise speed (> 0), acceleration and deceleration (> 0). */
struct plan_limits {
    int32_t vmax;
    int32_t acc;
    int32_t dec;
};

/* One tick toward target. Returns true once the reference rests on the target. */
bool planner_step_to(struct plan *p, int64_t target, const struct plan_limits *lim);

/* One tick of speed mode: ramp the velocity toward vel_target (signed). */
void planner_step_speed(struct plan *p, int32_t vel_target, const struct plan_limits *lim);

/* Highest speed from which the reference can still stop within dist (>= 0) braking at
 * dec per tick, in the discrete sense the planner uses. */
int32_t planner_brake_speed(int64_t dist, int32_t dec);

/* The distance the reference covers from speed v (>= 0) braking at dec per tick, in the
 * same discrete sense (this tick's step included): planner_brake_speed()'s inverse, so a
 * target this far ahead is reached by braking at once. */
int64_t planner_stop_distance(int32_t v, int32_t dec);

#endif
