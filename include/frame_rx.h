/* frame_rx.h - the frame receiver: fed one byte at a time from the UART receive
 * interrupt, it cuts the byte stream into frames (PROTOCOL.md §1-§2) and hands them to
 * the main loop through a single-producer/single-consumer queue.
 *
 * Interrupt side: frame_rx_byte() only. Main-loop side: everything else;
 * frame_rx_set_baud() and frame_rx_idle() must be called with the receive interrupt masked.
 *
 * Resynchronisation: every `D5 5D` seen inside a frame may start another candidate
 * frame (a "shadow"; one runs at a time). If the frame in progress turns out bad
 * (checksum, invalid ID or length, or an inter-byte gap), the shadows that completed with
 * a good checksum inside it are delivered after it, in order, and a running shadow takes
 * over; so a lost byte costs only the packet it was in, even when its stated length
 * swallows several packets sent back to back. If the frame in progress is good, the
 * shadows inside it were its payload and are dropped.
 *
 * The one oversize frame (PROTOCOL.md §10): LEN = 0xFF with INS 0xFF, sub 0xFE and block
 * type 0x02 is a firmware data block of 1031 bytes after LEN, plus CHK. The receiver
 * moves it into the single block buffer once those three bytes have arrived; every other
 * frame keeps the length its LEN states. */
#ifndef FRAME_RX_H
#define FRAME_RX_H

#include <stdbool.h>
#include <stdint.h>

#include "proto.h"

#define FRAME_SLOTS 4u    /* power of two: frames buffered between ISR and main loop */
#define FRAME_BYTES 257u  /* ID, LEN and the LEN bytes it counts (INS, params, CHK) */
#define FRAME_BLOCK_BYTES PROTO_UPDATE_DATA_FRAME /* ID, LEN, a §10 data block, CHK */
#define FRAME_BLOCK FRAME_SLOTS /* the block buffer's entry, after the slots */
#define FRAME_READY (2u * FRAME_SLOTS) /* queue entries: every slot and the block */

enum frame_status { FRAME_OK, FRAME_BAD_CHECKSUM };

/* One received frame, header stripped: buf = ID, LEN, INS, P1..Pn, CHK. A slot's frame
 * or the §10 data block: one type, so the main loop handles both alike. */
struct frame {
    uint32_t end_us; /* arrival time of the last byte */
    uint16_t len;    /* LEN + 2 (FRAME_BLOCK_BYTES for the block) */
    uint8_t status;  /* enum frame_status */
    uint8_t *buf;    /* the entry's buffer, set by frame_rx_init() */
};

/* Parse state of one candidate frame (ISR only). */
struct frame_parser {
    uint16_t pos;  /* bytes stored so far */
    uint16_t need; /* total bytes once LEN is known */
    uint8_t slot;  /* index into frame_rx.slot, or FRAME_BLOCK */
    uint8_t sum;
};

struct frame_rx {
    struct frame slot[FRAME_SLOTS + 1u]; /* the slots, then the block (FRAME_BLOCK) */
    uint8_t slot_buf[FRAME_SLOTS][FRAME_BYTES];
    uint8_t block_buf[FRAME_BLOCK_BYTES];
    uint8_t block_busy; /* block taken by a parser or published; ISR sets, release clears */
    /* Published frames: ISR writes ready_head, main loop writes ready_tail. */
    uint8_t ready[FRAME_READY];
    uint8_t ready_head, ready_tail;
    /* Slots given back by the main loop: main writes free_head, ISR writes free_tail. */
    uint8_t free_ring[FRAME_SLOTS];
    uint8_t free_head, free_tail;
    /* ISR-only state. */
    struct frame_parser main, shadow;
    uint8_t spare[FRAME_SLOTS]; /* slots the ISR dropped, reused before free_ring */
    uint8_t spare_count;
    uint8_t waiting[FRAME_SLOTS + 1u]; /* complete good shadows, oldest first */
    uint8_t waiting_count;
    uint8_t in_frame;       /* 1 while main is a frame in progress */
    uint8_t shadow_running; /* 1 while shadow is a frame in progress */
    uint8_t prev;           /* previous byte, for spotting D5 5D */
    uint32_t last_us;       /* arrival (end) of the previous byte */
    uint32_t gap_us;        /* §1 idle-line time-out; main loop sets it, irq masked */
    uint32_t byte_us;       /* one byte-time: arrivals are byte ends, gaps are idle line */
    uint32_t overruns;      /* frames lost because every slot was in use */
};

/* Empty receiver with the time-out for the given baud rate. */
void frame_rx_init(struct frame_rx *rx, uint32_t baud);

/* Inter-byte time-out of §1: 2 ms or 20 byte-times, whichever is longer. It is idle
 * line: from the end of one byte to the start of the next. */
uint32_t frame_rx_gap_us(uint32_t baud);

/* ISR: one received byte that arrived at now_us. Bounded time: its only loops run over
 * the few slots (at most FRAME_SLOTS + 1 steps) and the 5 bytes moved into the block
 * buffer when a §10 data block is recognised. */
void frame_rx_byte(struct frame_rx *rx, uint8_t byte, uint32_t now_us);

/* Main loop, irq masked: apply the inter-byte time-out at now_us (so a frame waiting
 * behind a broken one is delivered when the line falls quiet) and report whether the
 * receiver is idle, i.e. not in the middle of a frame. A reply may only start then. */
bool frame_rx_idle(struct frame_rx *rx, uint32_t now_us);

/* Main loop, irq masked: the baud rate changed; so do the time-outs. */
void frame_rx_set_baud(struct frame_rx *rx, uint32_t baud);

/* Main loop: the oldest published frame (a slot's or the data block), or 0. Stays valid
 * until frame_rx_release(). */
const struct frame *frame_rx_peek(struct frame_rx *rx);

/* Main loop: give the oldest published frame back to the receiver. */
void frame_rx_release(struct frame_rx *rx);

#endif
