/* sequence.h - running the stored trajectory (§4.7): which point the reference is
 * heading for, where it must come to rest (the last point before a reversal or the end),
 * and at which speed. The motion layer steps the planner; this module only sequences.
 * Main loop only. */
#ifndef SEQUENCE_H
#define SEQUENCE_H

#include <stdbool.h>
#include <stdint.h>

#include "planner.h"
#include "scale.h"
#include "traj.h"

/* Where the trajectory's points are: the scale and the counts at position 0. */
struct sequence_frame {
    struct scale sc;
    int64_t zero;
};

struct sequence {
    uint8_t next; /* point being approached */
    uint8_t stop; /* last point before a reversal or the end: the reference rests there */
};

enum sequence_event {
    SEQ_GO_ON,       /* nothing changes */
    SEQ_NEW_SPEED,   /* passed a point without stopping: cruise at sequence_speed() */
    SEQ_NEW_SEGMENT, /* rested at a reversal: new target and speed */
    SEQ_DONE,        /* rested at the last point */
};

/* Start at point 0 from the reference position; *target is where to rest first. */
void sequence_start(struct sequence *q, const struct traj *t, const struct sequence_frame *f,
                    int64_t from, int64_t *target);

/* After a planner step: p is the reference, rest whether it came to rest on *target. */
uint8_t sequence_step(struct sequence *q, const struct traj *t, const struct sequence_frame *f,
                      const struct plan *p, bool rest, int64_t *target);

/* The speed (units/s) of the point being approached. */
uint16_t sequence_speed(const struct sequence *q, const struct traj *t);

#endif
