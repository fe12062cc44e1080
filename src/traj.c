/* traj.c - TRAJECTORY WRITE decoding (PROTOCOL.md §4.7). */
#include "proto.h"
#include "traj.h"

uint8_t traj_write(struct traj *t, const struct regs *r, const uint8_t *p, uint8_t n)
{
    if (n < 1u)
        return ERR_INSTRUCTION;
    uint8_t count = p[0];
    uint8_t bytes = (uint8_t)(n - 1u);
    if (count == 0u) {
        if (bytes)
            return ERR_INSTRUCTION;
        traj_clear(t);
        return 0;
    }
    /* The point size is implied by the length: 4 (speed 16-bit) or 3 (speed 8-bit). */
    uint8_t size = (uint8_t)(bytes / count);
    if ((size != 3u && size != 4u) || (uint16_t)(size * count) != bytes)
        return ERR_INSTRUCTION;
    const uint8_t *q = &p[1];
    for (uint8_t i = 0; i < count; i++, q += size) {
        uint16_t speed = size == 4u ? proto_get16(&q[2]) : q[2];
        /* Speed 0 is refused (§4.7), 0x8000 too: bit 15 is the direction, the magnitude
         * 0 (§5.4); run, such a point crawled at the planner's least speed for ever. */
        if (proto_speed_is_stop(speed))
            return ERR_INSTRUCTION;
    }
    q = &p[1];
    for (uint8_t i = 0; i < count; i++, q += size) {
        t->pt[i].angle = regs_clamp_goal(r, proto_get16(&q[0]));
        t->pt[i].speed = size == 4u ? proto_get16(&q[2]) : q[2];
    }
    t->count = count;
    return 0;
}

void traj_clear(struct traj *t)
{
    t->count = 0;
}

void traj_clamp(struct traj *t, const struct regs *r)
{
    for (uint8_t i = 0; i < t->count; i++)
        t->pt[i].angle = regs_clamp_goal(r, t->pt[i].angle);
}
