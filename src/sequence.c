/* sequence.c - trajectory sequencing (sequence.h). */
#include "sequence.h"

/* A point's position, counts x 2^24. */
static int64_t point_pos(const struct traj *t, const struct sequence_frame *f, uint8_t i)
{
    return (f->zero + scale_units_to_counts(f->sc, t->pt[i].angle)) * PLANNER_ONE;
}

/* From point i, the last point reached without a change of direction. */
static uint8_t run_end(const struct traj *t, const struct sequence_frame *f, uint8_t i,
                       int64_t from)
{
    int64_t prev = from;
    int dir = 0;
    uint8_t j = i;
    for (; j < t->count; j++) {
        int64_t p = point_pos(t, f, j);
        int d = p > prev ? 1 : p < prev ? -1 : 0;
        if (dir && d && d != dir)
            break;
        if (d)
            dir = d;
        prev = p;
    }
    return (uint8_t)(j - 1u);
}

static void segment(struct sequence *q, const struct traj *t, const struct sequence_frame *f,
                    int64_t from, int64_t *target)
{
    q->stop = run_end(t, f, q->next, from);
    *target = point_pos(t, f, q->stop);
}

void sequence_start(struct sequence *q, const struct traj *t, const struct sequence_frame *f,
                    int64_t from, int64_t *target)
{
    q->next = 0;
    segment(q, t, f, from, target);
}

uint16_t sequence_speed(const struct sequence *q, const struct traj *t)
{
    return t->pt[q->next].speed;
}

uint8_t sequence_step(struct sequence *q, const struct traj *t, const struct sequence_frame *f,
                      const struct plan *p, bool rest, int64_t *target)
{
    int64_t pt = point_pos(t, f, q->next);
    bool passed = p->vel > 0 ? p->pos >= pt : p->vel < 0 ? p->pos <= pt : rest;
    if (passed && q->next < q->stop) {
        q->next++; /* through it without stopping: the next point's speed */
        return SEQ_NEW_SPEED;
    }
    if (!rest)
        return SEQ_GO_ON;
    if (q->stop + 1u >= t->count)
        return SEQ_DONE;
    q->next = (uint8_t)(q->stop + 1u);
    segment(q, t, f, p->pos, target);
    return SEQ_NEW_SEGMENT;
}
