/* homing.h - the photo-switch homing sequence of §9 as a state machine: it watches the
 * debounced switches and the travel, and tells the motion layer what to do next; the
 * motion layer drives, sets the zero and the limits, and keeps register 24. Main loop
 * only. */
#ifndef HOMING_H
#define HOMING_H

#include <stdbool.h>
#include <stdint.h>

enum homing_phase {
    HOMING_PHASE_BACKOFF,
    HOMING_PHASE_SEEK,
    HOMING_PHASE_REVERSE,
    HOMING_PHASE_RETURN,
};

/* What the motion layer does after a homing step. */
enum homing_event {
    HOMING_EVENT_RUN,  /* keep turning at homing speed in direction homing_dir() */
    HOMING_EVENT_ZERO, /* switch 1 found: zero at the switch edge, then run toward the end */
    HOMING_EVENT_END,  /* switch 2 found: the end is at the switch edge; return onto it */
    HOMING_EVENT_RETURN, /* returning onto the end from the overrun past switch 2 */
    HOMING_EVENT_FAIL, /* both switches at once, or a switch not found within the travel */
};

struct homing {
    int64_t from;       /* counts where the phase began */
    int64_t max_travel; /* counts a phase may run without finding its switch */
    uint8_t phase;      /* enum homing_phase */
};

/* Begin at counts with the switches as they are (register 48 layout). */
void homing_start(struct homing *h, uint8_t switches, int64_t counts, int64_t max_travel);

/* One control tick. */
uint8_t homing_step(struct homing *h, uint8_t switches, int64_t counts);

/* Switch 2 was found: homing is returning onto the end (§9 step 3: its own stop, which
 * the heartbeat does not cut). */
bool homing_returning(const struct homing *h);

/* +1 toward the end (switch 2), -1 toward zero (switch 1). */
int8_t homing_dir(const struct homing *h);

#endif
