/* safety.h - heartbeat (PROTOCOL.md §7.1) and protection unload (§7.2): detection runs
 * once per control tick on the readings it is handed; the motion layer acts on the event
 * it returns. It owns the live ERR bits (0-3 and 6) that every answer carries. Main loop
 * only. */
#ifndef SAFETY_H
#define SAFETY_H

#include <stdbool.h>
#include <stdint.h>

#include "board.h"
#include "regs.h"

#define SAFETY_HEARTBEAT_TICKS 500u /* 500 ms at 1 kHz */

struct safety {
    uint16_t quiet_ticks; /* control ticks since the last valid packet */
    uint8_t present;      /* conditions now, in ERR bit layout (bits 0-3, 6) */
    uint8_t latched;      /* conditions that unloaded the motor, until cleared */
    uint16_t volt_acc;    /* leaky accumulators: noise does not trip, a real fault does */
    uint16_t temp_acc;
    uint16_t stall_ticks;
    uint8_t unfit;        /* HAL_CAP_* the board needs and the port lacks (servo_init) */
};

/* One tick's readings. */
struct safety_inputs {
    uint16_t supply_mv;
    int16_t temperature_dc; /* 0.1 degree C */
    uint16_t current_ma;
    int16_t duty;           /* the drive of the last tick, per mille */
    int32_t vel_q8;         /* measured speed, counts/tick x 2^8 */
    bool moving;            /* a motion is commanded */
};

enum safety_event { SAFETY_NONE, SAFETY_UNLOAD, SAFETY_HEARTBEAT };

/* A valid packet addressed to this servo or broadcast arrived (dispatcher). */
void safety_packet_seen(struct safety *sf);

/* One control tick of detection against the limits in the table (registers 11, 12, 17,
 * 18) and the board's supply range. Returns what the motion layer must do now. */
uint8_t safety_tick(struct safety *sf, const struct regs *r, const struct board *b,
                    const struct safety_inputs *in);

/* The live ERR bits: conditions present now, and latched unloads. */
uint8_t safety_err(const struct safety *sf);

/* The shaft is stalled now (a stall fails homing). */
bool safety_stalled(const struct safety *sf);

/* The port lacks fittings the board needs (HAL_CAP_*, hal.h; 0: none): the servo is
 * unloaded for good, which register 25 does not clear (its motion commands are refused
 * with ERR bit 5, as while an unload is latched). */
void safety_unfit(struct safety *sf, uint8_t missing);

/* A protection unload is latched, or the port is unfit: the motor stays off. */
bool safety_unloaded(const struct safety *sf);

/* Register 25: may the latch be cleared (no latched condition is still present)? */
bool safety_may_clear(const struct safety *sf);
void safety_clear(struct safety *sf);

#endif
