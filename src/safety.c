/* safety.c - heartbeat and protection detection (see safety.h). */
#include "proto.h"
#include "safety.h"

#define ACC_TRIP 200u    /* ~50 ms of a steady fault (4 up per bad tick, 1 down per good) */
#define TEMP_TRIP 2000u  /* ~0.5 s for temperature */
#define STALL_DUTY 800   /* per mille, or 70 % of the current limit: pushing hard ... */
#define STALL_SPEED_Q8 64 /* ... while turning less than 1/4 count per tick ... */
#define STALL_TICKS 300u /* ... for 300 ms */

void safety_packet_seen(struct safety *sf)
{
    sf->quiet_ticks = 0;
}

/* Leaky accumulator: up fast while the condition holds, down slowly when it does not;
 * the condition is present from the trip level until the accumulator has drained. Not
 * inlined: one copy for voltage and temperature is 24 B smaller in the image. */
__attribute__((noinline)) static bool leaky(uint16_t *acc, bool bad, uint16_t trip, bool was)
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

uint8_t safety_tick(struct safety *sf, const struct regs *r, const struct board *b,
                    const struct safety_inputs *in)
{
    uint8_t now = 0;

    uint16_t mv = in->supply_mv;
    bool low = mv < b->supply_min_mv, high = mv > b->supply_max_mv;
    bool was_v = sf->present & (ERR_UNDER_VOLTAGE | ERR_OVER_VOLTAGE);
    if (leaky(&sf->volt_acc, low || high, ACC_TRIP, was_v))
        now |= low ? ERR_UNDER_VOLTAGE : high ? ERR_OVER_VOLTAGE
                                             : (uint8_t)(sf->present & (ERR_UNDER_VOLTAGE |
                                                                        ERR_OVER_VOLTAGE));

    int16_t t = in->temperature_dc;
    if (leaky(&sf->temp_acc, t > temperature_limit_dc(r->mem[REG_TEMPERATURE_LIMIT]), TEMP_TRIP,
              sf->present & ERR_OVER_TEMPERATURE))
        now |= ERR_OVER_TEMPERATURE;

    /* Over-current trips at once: a short circuit does not wait for a filter. A limit of
     * 0 means no limit. */
    uint8_t limit = r->mem[REG_CURRENT_LIMIT];
    uint16_t ma = in->current_ma;
    if (limit && ma > (uint16_t)(limit * 100u))
        now |= ERR_OVER_CURRENT;

    /* The motion layer limits the current, so a jammed shaft shows as a current near the
     * limit (or a drive near full when there is no limit) with no movement. */
    int16_t duty = in->duty;
    int32_t v = in->vel_q8;
    bool hard = (limit && ma >= (uint16_t)(limit * 70u)) || duty >= STALL_DUTY ||
                duty <= -STALL_DUTY;
    bool pushing = in->moving && hard && v < STALL_SPEED_Q8 && v > -STALL_SPEED_Q8;
    sf->stall_ticks = pushing ? (uint16_t)(sf->stall_ticks + 1u) : 0u;
    if (sf->stall_ticks >= STALL_TICKS)
        now |= ERR_STALL;

    sf->present = now;
    uint8_t unload = now & r->mem[REG_UNLOAD_CONDITIONS] & (uint8_t)~(ERR_CHECKSUM | ERR_INSTRUCTION);
    bool fresh = unload & (uint8_t)~sf->latched;
    sf->latched |= unload;

    if (fresh)
        return SAFETY_UNLOAD;
    if (r->mem[REG_HEARTBEAT_ENABLE] && sf->quiet_ticks < UINT16_MAX &&
        ++sf->quiet_ticks == SAFETY_HEARTBEAT_TICKS)
        return SAFETY_HEARTBEAT;
    return SAFETY_NONE;
}

/* Not inlined: one copy for its callers, smaller under -flto (measured). */
__attribute__((noinline)) uint8_t safety_err(const struct safety *sf)
{
    return (uint8_t)(sf->present | sf->latched);
}

bool safety_stalled(const struct safety *sf)
{
    return (sf->present & ERR_STALL) != 0u;
}

void safety_unfit(struct safety *sf, uint8_t missing)
{
    sf->unfit = missing;
}

bool safety_unloaded(const struct safety *sf)
{
    return (sf->latched | sf->unfit) != 0u;
}

bool safety_may_clear(const struct safety *sf)
{
    return (sf->present & sf->latched) == 0u;
}

void safety_clear(struct safety *sf)
{
    sf->latched = 0;
}
