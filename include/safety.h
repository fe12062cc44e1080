/* safety.h - heartbeat (PROTOCOL.md §7.1) and protection unload (§7.2): detection runs
 * once per control tick; the motion layer acts on what it reports. Main loop only. */
#ifndef SAFETY_H
#define SAFETY_H

#include <stdbool.h>
#include <stdint.h>

struct servo;

#define SAFETY_HEARTBEAT_TICKS 500u /* 500 ms at 1 kHz */

struct safety {
    uint16_t quiet_ticks; /* control ticks since the last valid packet */
    uint8_t present;      /* conditions now, in ERR bit layout (bits 0-3, 6) */
    uint8_t latched;      /* conditions that unloaded the motor, until cleared */
    uint16_t volt_acc;    /* leaky accumulators: noise does not trip, a real fault does */
    uint16_t temp_acc;
    uint16_t stall_ticks;
};

enum safety_event { SAFETY_NONE, SAFETY_UNLOAD, SAFETY_HEARTBEAT };

/* A valid packet addressed to this servo or broadcast arrived (dispatcher). */
void safety_packet_seen(struct servo *s);

/* One control tick of detection (after the sensors were read); sets the live ERR bits.
 * moving: a motion is commanded. Returns what the motion layer must do now. */
uint8_t safety_tick(struct servo *s, bool moving);

/* True while a protection unload is latched: motion commands are refused. */
bool safety_unloaded(const struct servo *s);

/* Register 25 := 1. Clears the latch if its conditions are gone; false (refused) if not. */
bool safety_may_clear(const struct servo *s);
void safety_clear(struct servo *s);

#endif
