/* frame_rx.c - byte-at-a-time frame receiver and its ISR-to-main-loop queue. */
#include <stddef.h>
#include <string.h>

#include "frame_rx.h"
#include "proto.h"

#define MASK (FRAME_SLOTS - 1u)
#define READY_MASK (FRAME_READY - 1u)
#define NO_SLOT 0xFFu

enum { STEP_MORE, STEP_DONE, STEP_INVALID };

_Static_assert((FRAME_SLOTS & MASK) == 0, "FRAME_SLOTS must be a power of two");
_Static_assert((FRAME_READY & READY_MASK) == 0 && FRAME_READY > FRAME_SLOTS,
               "the ready queue holds every slot and the block");
_Static_assert(FRAME_BYTES >= 2u + 255u, "a slot must hold the longest LEN");

/* Each ring index is written by one side only; the other side reads it with acquire so
 * it sees the slot contents written before the index moved. */
static uint8_t load_acquire(const uint8_t *p) { return __atomic_load_n(p, __ATOMIC_ACQUIRE); }
/* NOLINTNEXTLINE(readability-non-const-parameter): __atomic_store_n writes *p */
static void store_release(uint8_t *p, uint8_t v) { __atomic_store_n(p, v, __ATOMIC_RELEASE); }

uint32_t frame_rx_gap_us(uint32_t baud)
{
    uint32_t twenty_bytes = (200u * 1000000u + baud - 1u) / baud; /* 20 x 10 bits */
    return twenty_bytes > 2000u ? twenty_bytes : 2000u;
}

void frame_rx_init(struct frame_rx *rx, uint32_t baud)
{
    memset(rx, 0, sizeof *rx);
    for (uint8_t i = 0; i < FRAME_SLOTS; i++)
        rx->free_ring[i] = i;
    rx->free_head = FRAME_SLOTS;
    frame_rx_set_baud(rx, baud);
}

/* ISR and main loop: has the line been idle longer than the time-out before a byte
 * that ended (or a moment) at now_us? */
static bool gap_passed(const struct frame_rx *rx, uint32_t now_us)
{
    /* Signed: the main loop may ask with a time read just before a byte arrived. */
    return (int32_t)(now_us - rx->last_us) > (int32_t)(rx->gap_us + rx->byte_us);
}

/* ISR: a slot for a new candidate frame, or NO_SLOT when all are in use. */
static uint8_t slot_take(struct frame_rx *rx)
{
    if (rx->spare_count)
        return rx->spare[--rx->spare_count];
    uint8_t tail = rx->free_tail;
    if (tail == load_acquire(&rx->free_head))
        return NO_SLOT;
    uint8_t s = rx->free_ring[tail & MASK];
    store_release(&rx->free_tail, (uint8_t)(tail + 1u));
    return s;
}

static void slot_drop(struct frame_rx *rx, uint8_t s)
{
    if (s == FRAME_BLOCK)
        rx->block_busy = 0;
    else
        rx->spare[rx->spare_count++] = s;
}

static void slot_publish(struct frame_rx *rx, uint8_t s)
{
    uint8_t head = rx->ready_head;
    rx->ready[head & READY_MASK] = s;
    store_release(&rx->ready_head, (uint8_t)(head + 1u));
}

static void parser_start(struct frame_parser *p, uint8_t slot)
{
    p->slot = slot;
    p->pos = 0;
    p->need = FRAME_BYTES;
}

/* ISR: LEN 0xFF, INS 0xFF, sub 0xFE, type 0x02: a §10 data block, longer than any slot.
 * Move what arrived into the block buffer; false if it is in use (the block is lost and
 * the host, seeing no answer, sends it again). */
static bool parser_to_block(struct frame_rx *rx, struct frame_parser *p)
{
    if (load_acquire(&rx->block_busy)) {
        rx->overruns++;
        return false;
    }
    rx->block_busy = 1;
    /* A loop, not memcpy: this runs in the interrupt, from RAM (memcpy is in flash). */
    for (uint16_t i = 0; i < p->pos; i++)
        rx->block.buf[i] = rx->slot[p->slot].buf[i];
    slot_drop(rx, p->slot);
    p->slot = FRAME_BLOCK;
    p->need = FRAME_BLOCK_BYTES;
    return true;
}

/* ISR: feed one byte to a candidate frame. */
static uint8_t parser_step(struct frame_rx *rx, struct frame_parser *p, uint8_t b,
                           uint32_t now_us)
{
    uint8_t *buf = p->slot == FRAME_BLOCK ? rx->block.buf : rx->slot[p->slot].buf;
    buf[p->pos++] = b;
    if (p->pos == 1u) { /* ID */
        p->sum = b;
        return b == PROTO_ID_INVALID ? STEP_INVALID : STEP_MORE;
    }
    if (p->pos == 2u) { /* LEN: counts INS, parameters and CHK */
        p->sum = (uint8_t)(p->sum + b);
        p->need = (uint16_t)(b + 2u);
        return b < 2u ? STEP_INVALID : STEP_MORE;
    }
    if (p->pos < p->need) {
        p->sum = (uint8_t)(p->sum + b);
        if (p->pos == 5u && p->need == FRAME_BYTES && buf[2] == 0xFFu && buf[3] == 0xFEu &&
            b == 0x02u && !parser_to_block(rx, p))
            return STEP_INVALID;
        return STEP_MORE;
    }
    uint8_t status = b == p->sum ? FRAME_OK : FRAME_BAD_CHECKSUM;
    if (p->slot == FRAME_BLOCK) {
        rx->block.len = p->need;
        rx->block.end_us = now_us;
        rx->block.status = status;
    } else {
        struct frame *f = &rx->slot[p->slot];
        f->len = p->need;
        f->end_us = now_us;
        f->status = status;
    }
    return STEP_DONE;
}

/* ISR: status of the frame a parser just completed. */
static bool parser_good(const struct frame_rx *rx, const struct frame_parser *p)
{
    uint8_t status = p->slot == FRAME_BLOCK ? rx->block.status : rx->slot[p->slot].status;
    return status == FRAME_OK;
}

/* ISR: drop every shadow (they were the payload of a good frame). */
static void shadows_drop(struct frame_rx *rx)
{
    while (rx->waiting_count)
        slot_drop(rx, rx->waiting[--rx->waiting_count]);
    if (rx->shadow_running)
        slot_drop(rx, rx->shadow.slot);
    rx->shadow_running = 0;
}

/* ISR: the frame in progress is over and was bad: the good frames found inside it are
 * delivered, a running shadow becomes the frame in progress. */
static void main_failed(struct frame_rx *rx)
{
    for (uint8_t i = 0; i < rx->waiting_count; i++)
        slot_publish(rx, rx->waiting[i]);
    rx->waiting_count = 0;
    if (rx->shadow_running)
        rx->main = rx->shadow;
    else
        rx->in_frame = 0;
    rx->shadow_running = 0;
}

/* ISR and main loop: an inter-byte gap ends everything in progress. */
static void abandon(struct frame_rx *rx)
{
    slot_drop(rx, rx->main.slot);
    if (rx->shadow_running)
        slot_drop(rx, rx->shadow.slot);
    rx->shadow_running = 0;
    main_failed(rx);
}

void frame_rx_byte(struct frame_rx *rx, uint8_t b, uint32_t now_us)
{
    uint8_t prev = rx->prev;
    if (gap_passed(rx, now_us)) {
        if (rx->in_frame)
            abandon(rx);
        prev = 0; /* a header cannot straddle a gap */
    }
    rx->last_us = now_us;
    rx->prev = b;
    bool header = prev == PROTO_HEADER0 && b == PROTO_HEADER1;

    if (!rx->in_frame) {
        if (header) {
            uint8_t s = slot_take(rx);
            if (s == NO_SLOT) {
                rx->overruns++;
                return;
            }
            parser_start(&rx->main, s);
            rx->in_frame = 1;
        }
        return;
    }

    if (rx->shadow_running) {
        uint8_t r = parser_step(rx, &rx->shadow, b, now_us);
        if (r == STEP_DONE && parser_good(rx, &rx->shadow)) {
            rx->waiting[rx->waiting_count++] = rx->shadow.slot;
            rx->shadow_running = 0;
        } else if (r != STEP_MORE) {
            slot_drop(rx, rx->shadow.slot); /* noise inside the frame in progress */
            rx->shadow_running = 0;
        }
    } else if (header) {
        uint8_t s = slot_take(rx);
        if (s != NO_SLOT) {
            parser_start(&rx->shadow, s);
            rx->shadow_running = 1;
        }
    }

    uint8_t r = parser_step(rx, &rx->main, b, now_us);
    if (r == STEP_MORE)
        return;
    bool good = r == STEP_DONE && parser_good(rx, &rx->main);
    if (r == STEP_DONE)
        slot_publish(rx, rx->main.slot); /* bad checksums too: they may get an answer */
    else
        slot_drop(rx, rx->main.slot);
    if (good) {
        shadows_drop(rx); /* any header seen inside a good frame was its payload */
        rx->in_frame = 0;
        return;
    }
    main_failed(rx);
}

bool frame_rx_idle(struct frame_rx *rx, uint32_t now_us)
{
    if (rx->in_frame && gap_passed(rx, now_us)) {
        abandon(rx);
        rx->prev = 0;
    }
    return !rx->in_frame;
}

void frame_rx_set_baud(struct frame_rx *rx, uint32_t baud)
{
    rx->gap_us = frame_rx_gap_us(baud);
    rx->byte_us = (10u * 1000000u + baud - 1u) / baud;
}

/* Main loop: queue entry of the oldest published frame, or NO_SLOT. */
static uint8_t oldest(struct frame_rx *rx)
{
    uint8_t tail = rx->ready_tail;
    if (tail == load_acquire(&rx->ready_head))
        return NO_SLOT;
    return rx->ready[tail & READY_MASK];
}

const struct frame *frame_rx_peek(struct frame_rx *rx)
{
    uint8_t s = oldest(rx);
    return s < FRAME_SLOTS ? &rx->slot[s] : NULL;
}

const struct frame_block *frame_rx_peek_block(struct frame_rx *rx)
{
    return oldest(rx) == FRAME_BLOCK ? &rx->block : NULL;
}

void frame_rx_release(struct frame_rx *rx)
{
    uint8_t tail = rx->ready_tail;
    uint8_t s = rx->ready[tail & READY_MASK];
    store_release(&rx->ready_tail, (uint8_t)(tail + 1u));
    if (s == FRAME_BLOCK) {
        store_release(&rx->block_busy, 0);
        return;
    }
    uint8_t head = rx->free_head;
    rx->free_ring[head & MASK] = s;
    store_release(&rx->free_head, (uint8_t)(head + 1u));
}
