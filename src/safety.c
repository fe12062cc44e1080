/* safety.c - heartbeat and protection detection (see safety.h). */
#include "hal.h"
#include "proto.h"
#include "safety.h"
#include "servo.h"

#define ACC_TRIP 200u    /* ~50 ms of a steady fault (4 up per bad tick, 1 down per good) */
#define TEMP_TRIP 2000u  /* ~0.5 s for temperature */
#define STALL_DUTY 800   /* per mille, or 70 % of the current limit: pushing hard ... */
#define STALL_SPEED_Q8 64 /* ... while turning less than 1/4 count per tick ... */
#define STALL_TICKS 300u /* ... for 300 ms */

void safety_packet_seen(struct servo *s)
{
    s->safety.quiet_ticks = 0;
}

/* Leaky accumulator: up fast while the condition holds, down slowly when it does not;
 * the condition is present from the trip level until the accumulator has drained. */
static bool leaky(uint16_t *acc, bool bad, uint16_t trip, bool was)
{
    if (bad)
        *acc = (uint16_t)(*acc + 4u > trip ? trip : *acc + 4u);
    else if (*acc)
        (*acc)--;
    return was ? *acc > 0u : *acc >= trip;
}

/* Register 11: bit 7 sign, bits 0-6 degrees C. */
static int16_t temperature_limit_dc(uint8_t reg)
{
    int16_t deg = (int16_t)(reg & 0x7Fu);
    return (int16_t)((reg & 0x80u) ? -deg * 10 : deg * 10);
}

uint8_t safety_tick(struct servo *s, bool moving)
{
    struct safety *sf = &s->safety;
    const struct regs *r = &s->regs;
    uint8_t now = 0;

    uint16_t mv = hal_supply_mv(s->hal);
    bool low = mv < s->board->supply_min_mv, high = mv > s->board->supply_max_mv;
    bool was_v = sf->present & (ERR_UNDER_VOLTAGE | ERR_OVER_VOLTAGE);
    if (leaky(&sf->volt_acc, low || high, ACC_TRIP, was_v))
        now |= low ? ERR_UNDER_VOLTAGE : high ? ERR_OVER_VOLTAGE
                                             : (uint8_t)(sf->present & (ERR_UNDER_VOLTAGE |
                                                                        ERR_OVER_VOLTAGE));

    int16_t t = hal_temperature_dc(s->hal);
    if (leaky(&sf->temp_acc, t > temperature_limit_dc(r->mem[REG_TEMPERATURE_LIMIT]), TEMP_TRIP,
              sf->present & ERR_OVER_TEMPERATURE))
        now |= ERR_OVER_TEMPERATURE;

    /* Over-current trips at once: a short circuit does not wait for a filter. A limit of
     * 0 means no limit. */
    uint8_t limit = r->mem[REG_CURRENT_LIMIT];
    uint16_t ma = hal_motor_current_ma(s->hal);
    if (limit && ma > (uint16_t)(limit * 100u))
        now |= ERR_OVER_CURRENT;

    /* The motion layer limits the current, so a jammed shaft shows as a current near the
     * limit (or a drive near full when there is no limit) with no movement. */
    int16_t duty = s->motion.duty;
    int32_t v = s->motion.vel_q8;
    bool hard = (limit && ma >= (uint16_t)(limit * 70u)) || duty >= STALL_DUTY ||
                duty <= -STALL_DUTY;
    bool pushing = moving && hard && v < STALL_SPEED_Q8 && v > -STALL_SPEED_Q8;
    sf->stall_ticks = pushing ? (uint16_t)(sf->stall_ticks + 1u) : 0u;
    if (sf->stall_ticks >= STALL_TICKS)
        now |= ERR_STALL;

    sf->present = now;
    uint8_t unload = now & r->mem[REG_UNLOAD_CONDITIONS] & (uint8_t)~(ERR_CHECKSUM | ERR_INSTRUCTION);
    bool fresh = unload & (uint8_t)~sf->latched;
    sf->latched |= unload;
    s->live_err = (uint8_t)(now | sf->latched);

    if (fresh)
        return SAFETY_UNLOAD;
    if (r->mem[REG_HEARTBEAT_ENABLE] && sf->quiet_ticks < UINT16_MAX &&
        ++sf->quiet_ticks == SAFETY_HEARTBEAT_TICKS)
        return SAFETY_HEARTBEAT;
    return SAFETY_NONE;
}

bool safety_unloaded(const struct servo *s)
{
    return s->safety.latched != 0u;
}

bool safety_may_clear(const struct servo *s)
{
    return (s->safety.present & s->safety.latched) == 0u;
}

void safety_clear(struct servo *s)
{
    s->safety.latched = 0;
    s->live_err = s->safety.present;
}
