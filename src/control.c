/* control.c - encoder, speed filter, switch debouncing and the position loop
 * (control.h). */
#include "control.h"
#include "hal.h"

/* Controller gains, duty per mille: feed-forward per count/tick of reference speed,
 * friction feed-forward, proportional per count of position error, damping per
 * count/tick of speed error. Tuned on the reference gearmotor (hal/host/motor_sim.c). */
#define KFF 2
/* KFF x v / 256 is v / (256 / KFF), the same truncation, with no 64-bit product. */
_Static_assert(256 % KFF == 0, "KFF divides 256");
#define KFRICTION 30
#define KP 8
#define KD 60
#define DEBOUNCE_TICKS 5  /* photo switches: stable this long to count */
#define KI_SHIFT 2        /* integral gain 1/4 per count per tick, only at rest, */
#define INTEGRAL_MAX 1200 /* worth at most 300 per mille: beats static friction */

void control_init(struct control *c, int32_t raw, int8_t sign)
{
    *c = (struct control){0};
    c->raw = raw;
    c->sign = sign;
}

void control_measure(struct control *c, int32_t raw, uint8_t switches)
{
    int32_t delta = (int32_t)((uint32_t)raw - (uint32_t)c->raw) * c->sign;
    c->raw = raw;
    c->counts += delta;
    /* First-order filter, 1/8 per tick, its division remainder carried to the next tick:
     * no bias, and a shaft at rest reads exactly 0 (truncation alone left up to 7/256 of
     * a count per tick for ever: 1 unit/s). */
    int32_t dv = delta * 256 - c->vel_q8 + c->vel_rem;
    c->vel_q8 += dv / 8;
    c->vel_rem = (int8_t)(dv % 8);
    uint8_t sw = switches & 3u;
    if (sw != c->sw_raw) {
        c->sw_raw = sw;
        c->sw_count = 0;
        c->sw_edge = c->counts;
    } else if (c->sw_count < DEBOUNCE_TICKS && ++c->sw_count == DEBOUNCE_TICKS) {
        c->switches = sw;
    }
}

void control_mirror(struct control *c)
{
    c->sign = (int8_t)-c->sign;
    c->counts = -c->counts;
}

void control_engage(struct control *c)
{
    c->integral = 0;
}

void control_release(struct control *c)
{
    c->duty = 0;
}

/* Position loop with speed and friction feed-forward, and an integral term while the
 * reference rests (so static friction cannot leave a standing error), limited so the
 * winding current stays under 80 % of register 12: the current follows the difference
 * between the drive and the back-EMF, which the speed feed-forward constant measures in
 * duty units. So a reversal at speed or a hard stop brakes at the current limit instead
 * of tripping the over-current protection. */
int16_t control_duty(struct control *c, const struct plan *ref, const struct control_limits *lim)
{
    int64_t pos = (ref->pos + PLANNER_ONE / 2) >> PLANNER_SHIFT;
    int64_t err = pos - c->counts;
    /* Inside the hold band the integral rests: winding it up through static friction
     * would nudge the shaft a count at a time long after it stopped (hunting). */
    if (ref->vel == 0 && (err > CONTROL_HOLD_BAND || err < -CONTROL_HOLD_BAND) &&
        err > -INTEGRAL_MAX && err < INTEGRAL_MAX) {
        c->integral += (int32_t)err;
        if (c->integral > INTEGRAL_MAX)
            c->integral = INTEGRAL_MAX;
        if (c->integral < -INTEGRAL_MAX)
            c->integral = -INTEGRAL_MAX;
    }
    int32_t vref_q8 = ref->vel >> (PLANNER_SHIFT - 8);
    int64_t duty = vref_q8 / (256 / KFF) + (int64_t)KP * err +
                   /* cppcheck-suppress shiftNegativeLHS ; arithmetic right shift (docs/lint.md) */
                   ((int64_t)KD * (vref_q8 - c->vel_q8)) / 256 + (c->integral >> KI_SHIFT);
    if (ref->vel)
        duty += ref->vel > 0 ? KFRICTION : -KFRICTION;
    if (lim->current_limit) {
        /* 32 bits hold both: |emf| <= 2^31 / (256 / KFF) and
         * band <= 255 x 65535 x 8 / 100, their sum well under 2^31. */
        int32_t emf = c->vel_q8 / (256 / KFF);
        int32_t band = (int32_t)((uint32_t)lim->current_limit * lim->duty_per_amp * 8u / 100u);
        if (duty > emf + band)
            duty = emf + band;
        if (duty < emf - band)
            duty = emf - band;
    }
    if (duty > HAL_DUTY_MAX)
        duty = HAL_DUTY_MAX;
    if (duty < -HAL_DUTY_MAX)
        duty = -HAL_DUTY_MAX;
    c->duty = (int16_t)duty;
    return c->duty;
}
