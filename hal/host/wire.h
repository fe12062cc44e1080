/* wire.h - the bus line at the bit level (RS485 or single-wire TTL, 8N1), in nanoseconds.
 *
 * Talkers put bytes on the line, each at its own baud: a start bit (0), eight data bits
 * LSB first, a stop bit (1), back to back or with gaps. The line is the AND of every
 * talker's level: idle high, and a 0 of anyone dominates (an open-drain or RS485 bus
 * with fail-safe bias: two talkers at once garble each other, and where they send the
 * same bits at the same time the line shows exactly those bits).
 *
 * A receiver samples the line as a UART does, at its own baud: it hunts for a falling
 * edge; the start bit is sampled in its middle (a 1 there is noise: hunt on), then the
 * eight data bits and the stop bit in theirs. A stop bit read as 0 is a framing error:
 * the byte is dropped, as the STM32 port drops it (hal/stm32f1/uart.c). After the stop
 * bit's sample the receiver hunts again. So a byte sent at another baud arrives as
 * garbage or not at all. A receiver of baud 0 hears every baud: at each start bit it
 * takes the baud of the talker whose start bit it is (servo-sim's raw TCP host).
 *
 * Each talker's bytes must be put in time order and must not overlap one another; the
 * line is known as far as bytes have been put. Pure data, no clock: the caller decides
 * when a decoded byte is final (no talker can still start before its stop sample). */
#ifndef WIRE_H
#define WIRE_H

#include <stdbool.h>
#include <stdint.h>

#define WIRE_NS_PER_S 1000000000LL

struct wire_byte {
    int64_t start_ns; /* the start bit begins */
    int64_t end_ns;   /* its stop bit ends (wire_bit_ns(start_ns, baud, 10), kept: a
                       * receiver asks it of every talker at every bit boundary) */
    uint32_t baud;
    uint8_t byte;
};

/* One talker's bytes on the line, oldest first (a ring that grows as needed). */
struct wire_talker {
    struct wire_byte *q;
    uint32_t cap, head, len;
};

struct wire {
    unsigned talkers;
    struct wire_talker *t;
    unsigned *active; /* the talkers with bytes on the line, nactive of them */
    unsigned nactive;
    uint32_t changes; /* counts puts and drops: a receiver's decode is stale when it moved */
};

struct wire_rx {
    uint32_t baud;   /* 0: every baud */
    int64_t hunt_ns; /* looks for a falling edge from here on */
};

/* A byte a receiver decoded. */
struct wire_rx_byte {
    int64_t edge_ns; /* the falling edge that started it */
    int64_t stop_ns; /* its stop bit's sample: where the receiver hunts again */
    int64_t end_ns;  /* its stop bit's end: when the UART hands it over */
    uint32_t baud;   /* the receiver's, or the talker's for a baud-0 receiver */
    uint8_t byte;
    bool framing_ok; /* false: a framing error, dropped by a UART */
};

/* A line with this many talkers (numbered from 0), nothing on it. */
void wire_init(struct wire *w, unsigned talkers);
void wire_free(struct wire *w);

/* Time of bit boundary k (0 = start, 10 = end of the stop bit) of a byte starting at
 * start_ns at baud: start + ceil(k * 1e9 / baud). */
int64_t wire_bit_ns(int64_t start_ns, uint32_t baud, unsigned k);

/* Talker puts byte on the line at start_ns (not before the end of its previous byte). */
void wire_put(struct wire *w, unsigned talker, int64_t start_ns, uint32_t baud, uint8_t byte);

/* End of the talker's last byte on the line (INT64_MIN if it has none). */
int64_t wire_talker_end(const struct wire *w, unsigned talker);

/* True while one of the talker's bytes is on the line at t (start <= t < end). */
bool wire_talker_busy(const struct wire *w, unsigned talker, int64_t t);

/* When the talker's byte on the line at t ends (t if it has none there). */
int64_t wire_talker_free_at(const struct wire *w, unsigned talker, int64_t t);

/* The talker stops: its bytes that start after t are taken off the line. */
void wire_drop_after(struct wire *w, unsigned talker, int64_t t);

/* Forget every byte that ended before t (no receiver will look before t again). */
void wire_prune(struct wire *w, int64_t t);

/* Level of the line at t: 1 (idle, or every talker sends a 1) or 0. */
int wire_level(const struct wire *w, int64_t t);

/* The next byte r decodes from the line as it is known (framing errors included):
 * true and *out, or false when the known line holds no further byte for it. */
bool wire_rx_next(const struct wire *w, const struct wire_rx *r, struct wire_rx_byte *out);

/* r has taken b: it hunts again from b's stop sample. */
void wire_rx_take(struct wire_rx *r, const struct wire_rx_byte *b);

#endif
