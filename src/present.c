/* present.c - the present-state registers (present.h). */
#include "present.h"

void present_write(struct regs *r, const struct board *b, const struct present_inputs *in)
{
    regs_set(r, regs_position_addr(b), (uint16_t)in->position);
    regs_set(r, REG_PRESENT_SPEED, (uint16_t)in->speed);
    regs_put8(r, REG_MOVING, (uint8_t)in->moving); /* read-only RAM: nothing to mark */
    regs_put8(r, REG_PHOTO_SWITCHES, in->switches);
    /* Register 46 (every variant): rounded to the degree, bit 7 the sign. */
    int16_t dc = in->temperature_dc;
    uint32_t deg = ((uint32_t)(dc < 0 ? -dc : dc) + 5u) / 10u;
    regs_put8(r, REG_PRESENT_TEMPERATURE,
              (uint8_t)((deg > 127u ? 127u : deg) | (dc < 0 && deg ? 0x80u : 0u)));
}
