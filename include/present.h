/* present.h - the present-state registers (§5.1), written from the measurements once per
 * control tick, each 16-bit one in a single store (a READ between two ticks sees one
 * tick's values). Main loop only. */
#ifndef PRESENT_H
#define PRESENT_H

#include <stdbool.h>
#include <stdint.h>

#include "board.h"
#include "regs.h"

struct present_inputs {
    int32_t position;  /* position units from the zero */
    int16_t speed;     /* position units per second */
    bool moving;       /* a move, speed, trajectory, stop or homing is running */
    uint8_t switches;  /* photo switches, debounced */
    int16_t temperature_dc; /* 0.1 degree C */
};

void present_write(struct regs *r, const struct board *b, const struct present_inputs *in);

#endif
