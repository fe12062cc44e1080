/* frame_rx.h - the frame receiver: fed one byte at a time from the UART receive
 * interrupt, it cuts the byte stream into frames (PROTOCOL.md §1-§2) and hands them to
 * the main loop through a single-producer/single-consumer queue.
 *
 * Interrupt side: frame_rx_byte() only. Main-loop side: everything else;
 * frame_rx_set_baud(), frame_rx_idle() and frame_rx_quiet() must be called with the
 * receive interrupt masked.
 *
 * Resynchronisation (docs/architecture.md, "The receiver"): every `D5 5D` starts a
 * candidate frame. The oldest candidate in progress is the head; it owns a buffer, and
 * the candidates that start inside it are suffixes of its bytes, so they are records
 * (where in the stream they start, the stream's running sum there), not copies. Each has
 * two events: its LEN (ID 0xFF or LEN 0/1: dropped) and its checksum byte (bad: dropped;
 * good: it waits for the head, and what started inside it was its payload). When the
 * head is over:
 *   - good: it is a frame, and the candidates inside it were its payload;
 *   - bad checksum: it is a frame with a bad checksum (the main loop may answer it),
 *     then the good candidates inside it follow, in order, and the first one still
 *     running becomes the head (its bytes so far move to a slot of their own);
 *   - a gap (§1), ID 0xFF or LEN 0/1: the same, but it is not a frame, and at a gap
 *     whatever was still running is abandoned with it.
 * So a lost byte costs only the packet it was in, whatever the bytes around it: a good
 * packet found behind a broken one is delivered late, not lost. A frame or candidate
 * that finds no room (no buffer; no record, and the head around it then fails) is
 * counted in overruns.
 *
 * The one oversize frame (PROTOCOL.md §10): LEN = 0xFF with INS 0xFF, sub 0xFE and block
 * type 0x02 is a firmware data block of 1031 bytes after LEN, plus CHK. Once those three
 * bytes have arrived it takes every slot, whose buffers lie end to end and hold it; so it
 * needs them all free, as they are when an update host waits for each answer (else it is
 * dropped, counted, and the host, seeing no answer, sends it again). Every other frame
 * keeps the length its LEN states. */
#ifndef FRAME_RX_H
#define FRAME_RX_H

#include <stdbool.h>
#include <stdint.h>

#include "proto.h"

#define FRAME_SLOTS 4u    /* power of two: head buffers, and frames waiting in them */
#define FRAME_BYTES 257u  /* ID, LEN and the LEN bytes it counts (INS, params, CHK) */
#define FRAME_BLOCK_BYTES PROTO_UPDATE_DATA_FRAME /* ID, LEN, a §10 data block, CHK */
#define FRAME_BLOCK FRAME_SLOTS /* the block's buffer index: all the slots, end to end */
/* A slot's buffer: a frame, and a quarter of a §10 data block. */
#define FRAME_SLOT_BYTES ((FRAME_BLOCK_BYTES + FRAME_SLOTS - 1u) / FRAME_SLOTS)

/* Candidates inside the head (1), or the head alone (0): the bootloader's update mode,
 * whose host waits for the answer to every frame (docs/decisions.md, "Resynchronisation";
 * its flash goal). Its records then need only one per buffer. */
#ifndef FRAME_RX_INNER
#ifdef SERVO_BOOTLOADER
#define FRAME_RX_INNER 0
#else
#define FRAME_RX_INNER 1
#endif
#endif
#define FRAME_RECORDS (FRAME_RX_INNER ? 32u : 8u) /* power of two: frames waiting and
                                                   * candidates in progress */

enum frame_status { FRAME_OK, FRAME_BAD_CHECKSUM };

/* One received frame, header stripped: buf = ID, LEN, INS, P1..Pn, CHK. A slot's frame
 * or the §10 data block: one type, so the main loop handles both alike. */
struct frame {
    uint32_t end_us; /* arrival of the last byte (behind a broken frame: when delivered) */
    uint16_t len;    /* LEN + 2 (FRAME_BLOCK_BYTES for the block) */
    uint8_t status;  /* enum frame_status */
    uint8_t *buf;    /* inside the receiver's buffer, valid until frame_rx_release() */
};

/* A frame waiting for the main loop, or a candidate in progress (4 bytes: one word to
 * move). */
struct frame_rec {
    uint16_t at; /* a candidate: its first byte's stream position; a frame: its offset
                  * in its buffer */
    uint8_t tag; /* its buffer (a slot, or FRAME_BLOCK) and flags: frame_rx.c */
    uint8_t sum; /* a candidate: the stream's running sum before its first byte */
} __attribute__((aligned(4)));

struct frame_rx {
    uint8_t buf[FRAME_SLOTS * FRAME_SLOT_BYTES]; /* the slots, or one §10 data block */
    /* Records in stream order, a ring: [tail, ready) published frames for the main loop,
     * [ready, end) the candidates in progress, the head first. The ISR writes ready, end
     * and the records from ready on; the main loop writes tail. */
    struct frame_rec rec[FRAME_RECORDS];
    uint32_t end_us[FRAME_SLOTS + 1u]; /* per buffer: when its frames were published */
    uint8_t rec_tail, rec_ready, rec_end;
    /* Slots given back by the main loop: main writes free_head, ISR writes free_tail. */
    uint8_t free_ring[FRAME_SLOTS];
    uint8_t free_head, free_tail;
    /* A §10 data block holds the slots (none may be taken): the ISR sets it, and clears
     * it only if no frame was published from the block; else its last one's release
     * does. block_slot: the slot its head began in, given back with it. */
    uint8_t block_busy, block_slot;
    /* ISR-only state. Stream positions count the bytes received while there is a head
     * (a candidate is never more than a block behind), modulo 2^16. */
    uint8_t spare[FRAME_SLOTS]; /* slots the ISR dropped, reused before free_ring */
    uint8_t spare_count;
    uint8_t in_frame;  /* 1 while there is a head */
    uint8_t prev;      /* previous byte, for spotting D5 5D */
    uint8_t sum;       /* running sum of the bytes received while there is a head */
    uint8_t hsum;      /* the running sum before the head's first byte */
    uint8_t lost;      /* candidates inside the head that found no record */
    uint8_t *hbuf;     /* the head's buffer */
    uint16_t pos;      /* the next byte's stream position (while there is a head) */
    uint16_t hstart;   /* the head's first byte's */
    uint16_t hneed;    /* the head's length once LEN is known */
    uint16_t head_at;  /* the head's next event: its LEN, a §10 block's type, its end */
    uint16_t len_at;   /* the newest candidate inside the head: its LEN byte's */
    uint16_t chk_at;   /* the nearest checksum byte of a candidate inside the head */
    uint16_t next_ev;  /* the nearest of the three: the one comparison most bytes cost */
    uint32_t last_us;  /* arrival (end) of the previous byte */
    uint32_t gap_us;   /* §1 idle-line time-out; main loop sets it, irq masked */
    uint32_t byte_us;  /* one byte-time: arrivals are byte ends, gaps are idle line */
    uint32_t quiet_us; /* gap_us + byte_us: arrival to arrival, the longest in a frame */
    uint32_t overruns; /* frames or candidates dropped for want of room */
    /* Main-loop state. */
    struct frame view;   /* the frame frame_rx_peek() returned */
    uint32_t quiet_last; /* last_us when the line was found rested (frame_rx_quiet) */
    uint8_t quiet_seen;  /* quiet_last is valid */
};

/* Empty receiver with the time-out for the given baud rate. */
void frame_rx_init(struct frame_rx *rx, uint32_t baud);

/* Inter-byte time-out of §1: 2 ms or 20 byte-times, whichever is longer. It is idle
 * line: from the end of one byte to the start of the next. */
uint32_t frame_rx_gap_us(uint32_t baud);

/* ISR: one received byte that arrived at now_us. Bounded time: its loops run over the
 * records (at most FRAME_RECORDS steps: a candidate's checksum byte, the head's end) and,
 * when a head moves to another buffer (a candidate taking over, a §10 data block
 * recognised), over its bytes so far, a word at a time (at most FRAME_BYTES). */
void frame_rx_byte(struct frame_rx *rx, uint8_t byte, uint32_t now_us);

/* Main loop, irq masked: apply the inter-byte time-out at now_us (so a frame waiting
 * behind a broken one is delivered when the line falls quiet) and report whether the
 * receiver is idle, i.e. not in the middle of a frame. A reply may only start then. */
bool frame_rx_idle(struct frame_rx *rx, uint32_t now_us);

/* Main loop, irq masked: has the line rested for longer than the §1 time-out, with no
 * frame in progress? Flash work that stalls the main loop for tens of milliseconds (a
 * page erase) waits for this: frames sent back to back never meet the stall. */
bool frame_rx_quiet(struct frame_rx *rx, uint32_t now_us);

/* Main loop, irq masked: the baud rate changed; so do the time-outs. */
void frame_rx_set_baud(struct frame_rx *rx, uint32_t baud);

/* Main loop: the oldest published frame (a slot's or the data block), or 0. Stays valid
 * until frame_rx_release(). */
const struct frame *frame_rx_peek(struct frame_rx *rx);

/* Main loop: give the oldest published frame back to the receiver. */
void frame_rx_release(struct frame_rx *rx);

/* Frames or candidates dropped for want of room so far (servo-sim reports them). */
static inline uint32_t frame_rx_dropped(const struct frame_rx *rx)
{
    return rx->overruns;
}

#endif
