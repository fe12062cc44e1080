/* traj.h - the stored trajectory of TRAJECTORY WRITE (PROTOCOL.md §4.7): validation and
 * storage only; the motion layer runs it. */
#ifndef TRAJ_H
#define TRAJ_H

#include <stdbool.h>
#include <stdint.h>

#include "proto.h"
#include "regs.h"

/* One packet carries at most 84 points in the 3-byte form (a count byte and 3 bytes a
 * point in PROTO_PARAMS_MAX), 63 in the 4-byte form; the store holds whatever one packet
 * can carry. */
#define TRAJ_POINTS_MAX ((PROTO_PARAMS_MAX - 1u) / 3u)

struct traj_point {
    uint16_t angle; /* position units, clamped to the angle limits */
    uint16_t speed; /* position units per second, never 0 */
};

struct traj {
    struct traj_point pt[TRAJ_POINTS_MAX];
    uint8_t count;
};

/* Replace the stored trajectory with the parameters of a TRAJECTORY WRITE (count, then
 * the points). All or nothing: returns 0, or ERR_INSTRUCTION leaving t unchanged. */
uint8_t traj_write(struct traj *t, const struct regs *r, const uint8_t *p, uint8_t n);

/* No trajectory is stored (TRAJECTORY ACTION is refused). */
static inline bool traj_empty(const struct traj *t)
{
    return t->count == 0u;
}

/* Forget the stored points. */
void traj_clear(struct traj *t);

/* Clamp the stored points to the angle limits in force (new limits, and the start of a
 * run: a trajectory stored before the limits narrowed stays within the new ones). */
void traj_clamp(struct traj *t, const struct regs *r);

#endif
