/* homing.c - the §9 homing sequence (homing.h): off switch 1 if it starts on it, toward
 * switch 1 (zero), then toward switch 2 (the end). */
#include "homing.h"

void homing_start(struct homing *h, uint8_t switches, int64_t counts, int64_t max_travel)
{
    h->phase = (switches & 1u) ? HOMING_PHASE_BACKOFF : HOMING_PHASE_SEEK;
    h->from = counts;
    h->max_travel = max_travel;
}

int8_t homing_dir(const struct homing *h)
{
    return h->phase == HOMING_PHASE_SEEK ? -1 : 1;
}

uint8_t homing_step(struct homing *h, uint8_t switches, int64_t counts)
{
    int64_t travel = counts - h->from;
    if (switches == 3u || travel > h->max_travel || travel < -h->max_travel)
        return HOMING_EVENT_FAIL;
    switch (h->phase) {
    case HOMING_PHASE_BACKOFF:
        if (!(switches & 1u)) {
            h->phase = HOMING_PHASE_SEEK;
            h->from = counts;
        }
        return HOMING_EVENT_RUN;
    case HOMING_PHASE_SEEK:
        if (switches & 1u) { /* positions count up from here toward the end */
            h->phase = HOMING_PHASE_REVERSE;
            h->from = counts;
            return HOMING_EVENT_ZERO;
        }
        return HOMING_EVENT_RUN;
    case HOMING_PHASE_REVERSE:
        if (switches & 2u) {
            h->phase = HOMING_PHASE_RETURN;
            return HOMING_EVENT_END;
        }
        return HOMING_EVENT_RUN;
    default:
        return HOMING_EVENT_RETURN;
    }
}

bool homing_returning(const struct homing *h)
{
    return h->phase == HOMING_PHASE_RETURN;
}
