/* link.h - the servo's side of the bus: the settings in force (ID, baud, return delay,
 * status return level, error reporting) and the one status packet being scheduled or
 * sent. Settings written by the host take effect only when no answer is pending, i.e.
 * after the answer to the write has left the wire (PROTOCOL.md §1). Main loop only. */
#ifndef LINK_H
#define LINK_H

#include <stdbool.h>
#include <stdint.h>

#include "board.h"
#include "proto.h"
#include "regs.h"

struct servo;

#define LINK_DELAY_UNIT_US 500u /* register 5: the return delay in 500 us units (§5) */

enum link_state { LINK_IDLE, LINK_WAITING, LINK_SENDING };

struct link {
    uint32_t baud;
    uint8_t id;
    uint8_t level;  /* register 16 */
    uint8_t report; /* register 18 bits 4-5 */
    uint8_t delay;  /* register 5 */
    uint8_t state;  /* enum link_state */
    uint8_t relatch; /* settings were written: in force once no answer is pending */
    uint16_t tx_len;
    uint32_t due_us;
    uint8_t tx[PROTO_STATUS_MAX];
};

/* Baud rate of register 4's code on this board (§5.2); 0 for an unknown code. */
uint32_t link_baud(const struct board *b, uint8_t code);

/* Does a write of n bytes at addr leave register 4 at a code whose rate the UART makes
 * within 2 % on the clock in force (hal_uart_baud_achieved)? True if the write does not
 * touch register 4. A fall-back clock cannot make the top rates: the write is refused
 * rather than leave the servo talking at a rate no host uses. */
bool link_baud_reachable(const struct servo *s, uint8_t addr, const uint8_t *data, uint8_t n);

/* Time on the wire of n bytes at baud, in microseconds, rounded up. */
uint32_t link_bytes_us(uint32_t baud, uint32_t n);

/* When the answer to a frame that ended at end_us may start: after the return delay in
 * force (§5, register 5). */
uint32_t link_reply_at(const struct link *l, uint32_t end_us);

/* Take the table's settings into force unconditionally: the UART's baud and the RS485
 * terminator (register 20) included (power-up, update mode). */
void link_latch(struct servo *s);

/* A register write changed a setting (3, 4, 5, 16, 18, 20) or RESET restored them: they
 * take effect once no answer is pending (§1), in link_poll(). */
void link_settings_written(struct link *l);

/* The settings in force. */
static inline uint8_t link_id(const struct link *l)
{
    return l->id;
}

static inline uint32_t link_baud_in_force(const struct link *l)
{
    return l->baud;
}
static inline uint8_t link_level(const struct link *l)
{
    return l->level;
}

/* §3.2: a checksum error is answered at level 2 with register 18 bit 4; an instruction
 * error wherever register 18 bit 5 allows. */
static inline bool link_answers_checksum_errors(const struct link *l)
{
    return l->level == 2u && (l->report & UNLOAD_REPORT_CHECKSUM);
}

static inline bool link_answers_instruction_errors(const struct link *l)
{
    return (l->report & UNLOAD_REPORT_INSTRUCTION) != 0u;
}

/* §4.1: the delay of this servo's answer to a broadcast PING after its return delay, one
 * 7-byte answer plus two byte-times per ID below it. */
uint32_t link_ping_slot_us(const struct link *l);

/* Schedule a status packet to start at at_us (not before the receiver is idle). */
void link_answer(struct servo *s, uint8_t id, uint8_t err, const uint8_t *data, uint8_t n,
                 uint32_t at_us);

/* Advance the answer in progress; when it has left the wire, take written settings into
 * force. Returns true when the link is idle; rx_idle says whether the receiver is between
 * frames (an answer never starts while one arrives). */
bool link_poll(struct servo *s, uint32_t now_us, bool rx_idle);

/* Written settings wait for no answer to be pending (link_poll() takes them then). */
static inline bool link_relatch_due(const struct link *l)
{
    return l->relatch && l->state == LINK_IDLE;
}

/* An answer has been scheduled but its first byte has not left yet (a return delay, a
 * broadcast PING's slot): frames arriving meanwhile are still executed. */
/* LINK_IDLE, LINK_WAITING (an answer waits for its time) or LINK_SENDING. */
static inline uint8_t link_state(const struct link *l)
{
    return l->state;
}

/* When the answer that waits (LINK_WAITING) starts: servo-sim's bus orders the servos'
 * answers by it. */
static inline uint32_t link_due_us(const struct link *l)
{
    return l->due_us;
}

/* An answer waits and reports no checksum or instruction error (tx[4]: the ERR byte of
 * D5 5D ID LEN ERR ...): the kind a frame's error answer must not replace. */
static inline bool link_waiting_good(const struct link *l)
{
    return l->state == LINK_WAITING && (l->tx[4] & (ERR_CHECKSUM | ERR_INSTRUCTION)) == 0u;
}

#endif
