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
    uint16_t tx_len;
    uint32_t due_us;
    uint8_t tx[PROTO_STATUS_MAX];
};

/* Baud rate of register 4's code on this board (§5.2); 0 for an unknown code. */
uint32_t link_baud(const struct board *b, uint8_t code);

/* Time on the wire of n bytes at baud, in microseconds, rounded up. */
uint32_t link_bytes_us(uint32_t baud, uint32_t n);

/* When the answer to a frame that ended at end_us may start: after the return delay in
 * force (§5, register 5). */
uint32_t link_reply_at(const struct link *l, uint32_t end_us);

/* Take the table's settings into force (and the UART's baud) unconditionally. */
void link_latch(struct servo *s);

/* Schedule a status packet to start at at_us (not before the receiver is idle). */
void link_answer(struct servo *s, uint8_t id, uint8_t err, const uint8_t *data, uint8_t n,
                 uint32_t at_us);

/* Advance the answer in progress. Returns true when the link is idle and the next frame
 * may be dispatched; rx_idle says whether the receiver is between frames. */
bool link_poll(struct servo *s, uint32_t now_us, bool rx_idle);

#endif
