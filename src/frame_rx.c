/* frame_rx.c - byte-at-a-time frame receiver and its ISR-to-main-loop queue. */
#include <stddef.h>
#include <string.h>

#include "frame_rx.h"
#include "proto.h"

#define MASK (FRAME_SLOTS - 1u)
#define RMASK (FRAME_RECORDS - 1u)
#define NO_SLOT 0xFFu
#define NONE 0xFFFFu /* hneed: no such length (beyond every buffer) */

/* A record's tag: its buffer, and flags. */
#define TAG_BUF 0x07u  /* the buffer: a slot, or FRAME_BLOCK */
#define TAG_OK 0x10u   /* complete with a good checksum */
#define TAG_BAD 0x20u  /* published with a bad checksum */
#define TAG_LAST 0x40u /* the last published frame in its buffer: its release frees it */

/* How a head ends (head_over). */
enum { HEAD_GOOD, HEAD_BAD, HEAD_DROP };

_Static_assert((FRAME_SLOTS & MASK) == 0, "FRAME_SLOTS must be a power of two");
_Static_assert((FRAME_RECORDS & RMASK) == 0 && FRAME_RECORDS <= 128u &&
               FRAME_RECORDS > FRAME_SLOTS + 1u,
               "FRAME_RECORDS: a power of two that uint8_t indices count, a record per buffer");
_Static_assert(FRAME_BLOCK <= TAG_BUF, "a tag holds every buffer index");
_Static_assert(FRAME_SLOT_BYTES >= FRAME_BYTES && FRAME_SLOT_BYTES >= 2u + 255u,
               "a slot must hold the longest LEN");
_Static_assert(FRAME_SLOTS * FRAME_SLOT_BYTES >= FRAME_BLOCK_BYTES, "the slots hold a block");
_Static_assert(FRAME_BLOCK_BYTES + FRAME_BYTES < 0x8000u,
               "a head and what runs on from it fit the 16-bit stream positions");
_Static_assert(sizeof(struct frame_rec) == 4u, "a record is one word");

/* Each ring index is written by one side only; the other side reads it with acquire so
 * it sees the contents written before the index moved. */
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

/* ISR and main loop: the buffer with index s: a slot, or FRAME_BLOCK (all of them, from
 * the first). */
static uint8_t *buf_of(struct frame_rx *rx, uint8_t s)
{
    return s == FRAME_BLOCK ? rx->buf : rx->buf + (size_t)s * FRAME_SLOT_BYTES;
}

static struct frame_rec *rec_at(struct frame_rx *rx, uint8_t i)
{
    return &rx->rec[i & RMASK];
}

/* ISR and main loop: has the line been idle longer than the time-out before a byte
 * that ended (or a moment) at now_us? */
static bool gap_passed(const struct frame_rx *rx, uint32_t now_us)
{
    /* Signed: the main loop may ask with a time read just before a byte arrived. */
    return (int32_t)(now_us - rx->last_us) > (int32_t)rx->quiet_us;
}

/* ISR: a slot for a head, or NO_SLOT when all are in use (a §10 block holds them all). */
static uint8_t slot_take(struct frame_rx *rx)
{
    if (load_acquire(&rx->block_busy))
        return NO_SLOT;
    if (rx->spare_count)
        return rx->spare[--rx->spare_count];
    uint8_t tail = rx->free_tail;
    if (tail == load_acquire(&rx->free_head))
        return NO_SLOT;
    uint8_t s = rx->free_ring[tail & MASK];
    store_release(&rx->free_tail, (uint8_t)(tail + 1u));
    return s;
}

/* ISR: a buffer nothing published uses is free again (the block: the slots). */
static void slot_drop(struct frame_rx *rx, uint8_t s)
{
    if (s == FRAME_BLOCK) {
        s = rx->block_slot;
        rx->block_busy = 0;
    }
    rx->spare[rx->spare_count++] = s;
}

/* ISR: the slots for a §10 data block, if the head's (slot s) is the only one in use. */
static bool block_take(struct frame_rx *rx, uint8_t s)
{
    uint8_t free = (uint8_t)(load_acquire(&rx->free_head) - rx->free_tail);
    if ((uint8_t)(rx->spare_count + free) != FRAME_SLOTS - 1u)
        return false;
    rx->block_slot = s;
    rx->block_busy = 1;
    return true;
}

/* ISR: n bytes from src to dst, a word at a time (unaligned words are fine on the
 * Cortex-M3); dst may lie below src in the same buffer. Not memcpy: this runs in the
 * interrupt, from RAM, and memcpy is in flash. */
static void copy_bytes(uint8_t *dst, const uint8_t *src, uint16_t n)
{
    uint32_t k = 0; /* not 16-bit: no zero-extension per word */
    for (; FRAME_RX_INNER && k + 4u <= n; k += 4u) { /* the bootloader: 5 bytes at most */
        uint32_t w;
        __builtin_memcpy(&w, src + k, 4);
        __builtin_memcpy(dst + k, &w, 4);
    }
    for (; k < n; k++)
        dst[k] = src[k];
}

/* ISR: byte q is the LEN byte b of the newest candidate inside the head: ID 0xFF or LEN
 * 0/1 drop it, else its checksum byte becomes an event. Only the newest can be at its
 * LEN: two headers are at least two bytes apart. Unless it went already (payload of a
 * frame that completed on its first byte, or now the head itself). */
static void inner_len(struct frame_rx *rx, uint16_t q, uint8_t b)
{
    uint8_t last = (uint8_t)(rx->rec_end - 1u);
    if (last == rx->rec_ready || rec_at(rx, last)->at != (uint16_t)(q - 1u))
        return;
    if (rx->hbuf[(uint16_t)(q - 1u - rx->hstart)] == PROTO_ID_INVALID || b < 2u) {
        rx->rec_end--;
        return;
    }
    uint16_t chk = (uint16_t)(q + b);
    if ((uint16_t)(chk - q) < (uint16_t)(rx->chk_at - q))
        rx->chk_at = chk;
}

/* ISR: byte q (b; the running sum before it, s) is the checksum byte of candidates
 * inside the head: a good one is complete and waits for the head, and whatever started
 * inside it was its payload; a bad one is noise and goes. Then the next such byte.
 * One pass that keeps the records it does not drop. */
static void inner_chk(struct frame_rx *rx, uint16_t q, uint8_t b, uint8_t s)
{
    uint16_t next = 0xFFFFu; /* distance from q: none */
    uint8_t w = (uint8_t)(rx->rec_ready + 1u);
    for (uint8_t i = w; i != rx->rec_end; i++) {
        struct frame_rec r = *rec_at(rx, i);
        if (!(r.tag & TAG_OK) && r.at != q) { /* its LEN is here: its end is known */
            uint16_t len_at = (uint16_t)(r.at + 1u);
            uint16_t end = (uint16_t)(len_at + rx->hbuf[(uint16_t)(len_at - rx->hstart)]);
            if (end == q) {
                if ((uint8_t)(s - r.sum) != b)
                    continue;
                r.tag |= TAG_OK;
                *rec_at(rx, w++) = r;
                rx->prev = 0; /* a D5 5D ending on its checksum byte is its payload too */
                break; /* every later record started inside this frame */
            }
            if ((uint16_t)(end - q) < next)
                next = (uint16_t)(end - q);
        }
        *rec_at(rx, w++) = r;
    }
    rx->rec_end = w;
    rx->chk_at = (uint16_t)(q + next);
}

/* ISR: the head's next event after n bytes (its LEN; the type byte of what may be a §10
 * block; its checksum byte). A function of its own: two callers, 24 bytes less. */
__attribute__((noinline)) static void head_next(struct frame_rx *rx, uint16_t n)
{
    uint16_t at = 1u;
    if (n >= 2u)
        at = n <= 4u && rx->hneed == FRAME_BYTES ? 4u : (uint16_t)(rx->hneed - 1u);
    rx->head_at = (uint16_t)(rx->hstart + at);
}

/* ISR: a new head, the candidate whose first byte is at stream position `at` (the
 * running sum before it, sum), in buffer `to`; the bytes it has so far (from the old
 * head's, if any) move there. The caller sets its length and next event. */
static void head_start(struct frame_rx *rx, uint8_t to, uint16_t at, uint8_t sum)
{
    uint8_t *dst = buf_of(rx, to);
    copy_bytes(dst, rx->hbuf + (uint16_t)(at - rx->hstart), (uint16_t)(rx->pos - at));
    rec_at(rx, rx->rec_ready)->tag = to;
    rx->hbuf = dst;
    rx->hstart = at;
    rx->hsum = sum;
    rx->in_frame = 1;
}

/* ISR and main loop (irq masked): the head is over, `how`. Good: it is a frame and what
 * started inside it was its payload. Bad checksum: it is a frame (the main loop may
 * answer it), then the good candidates inside it follow in order (late rather than
 * lost), and the first one still running becomes the head in a slot of its own.
 * Dropped (ID 0xFF, LEN 0/1, a gap, a §10 block with no room): no frame, only the good
 * candidates inside it; what was still running goes with it (at a gap it has the gap
 * inside it too; otherwise there is none: nothing starts inside the first two bytes).
 * Candidates that found no record count as dropped, unless it was good. */
static void head_over(struct frame_rx *rx, uint8_t how, uint32_t now_us)
{
    uint8_t h = rx->rec_ready, end = rx->rec_end, w = h;
    uint8_t old = rec_at(rx, h)->tag;
    rx->end_us[old] = now_us;
    rx->in_frame = 0;
    if (how == HEAD_GOOD) { /* most frames: a frame, and what started inside it payload */
        *rec_at(rx, h) = (struct frame_rec){0, (uint8_t)(old | TAG_OK | TAG_LAST), 0};
        rx->rec_end = (uint8_t)(h + 1u);
        rx->lost = 0; /* what found no record was its payload too */
        rx->prev = 0; /* so is a D5 5D ending on its checksum byte (frame_rx_byte) */
        store_release(&rx->rec_ready, (uint8_t)(h + 1u));
        return;
    }
    if (how == HEAD_BAD)
        *rec_at(rx, w++) = (struct frame_rec){0, (uint8_t)(old | TAG_BAD), 0};
    uint8_t i = FRAME_RX_INNER ? (uint8_t)(h + 1u) : end; /* the candidates inside it */
    for (; i != end; i++) {
        struct frame_rec r = *rec_at(rx, i);
        if (r.tag & TAG_OK) /* late rather than lost: a frame in the old head's buffer */
            *rec_at(rx, w++) = (struct frame_rec){(uint16_t)(r.at - rx->hstart), (uint8_t)(old | TAG_OK), 0};
        else if (how == HEAD_BAD)
            break; /* still running: it becomes the head (and here i == w) */
    }
    if (w != h)
        rec_at(rx, (uint8_t)(w - 1u))->tag |= TAG_LAST;
    else
        slot_drop(rx, old);
    store_release(&rx->rec_ready, w);
    rx->rec_end = w;
    if (i != end) { /* never without FRAME_RX_INNER */
        uint8_t to = slot_take(rx);
        if (to != NO_SLOT) {
            struct frame_rec r = *rec_at(rx, i);
            uint16_t n = (uint16_t)(rx->pos - r.at);
            rx->rec_end = end;
            head_start(rx, to, r.at, r.sum);
            rx->hneed = n < 2u ? NONE : (uint16_t)(rx->hbuf[1] + 2u);
            head_next(rx, n);
            return;
        }
        rx->overruns++; /* it, and what started inside it */
    }
    rx->overruns += rx->lost;
    rx->lost = 0;
}

/* ISR: byte q (b; the running sum before it, s) is the head's event: its LEN, the type
 * byte of what may be a §10 data block, or its checksum byte. */
static void head_event(struct frame_rx *rx, uint16_t q, uint8_t b, uint8_t s, uint32_t now_us)
{
    uint16_t pos = (uint16_t)(q - rx->hstart);
    if (pos == 1u) { /* LEN: counts INS, parameters and CHK */
        if (rx->hbuf[0] == PROTO_ID_INVALID || b < 2u) {
            head_over(rx, HEAD_DROP, now_us);
            return;
        }
        rx->hneed = (uint16_t)(b + 2u);
    } else if (pos == 4u && rx->hneed == FRAME_BYTES && rx->hbuf[2] == INS_CUSTOM &&
               rx->hbuf[3] == PROTO_UPDATE_SUB_BLOCK && b == PROTO_UPDATE_TYPE_DATA) {
        /* A §10 data block: every slot, the head's bytes to the first (no candidate
         * started inside these five bytes). A slot in use: the block is lost; the host,
         * seeing no answer, sends it again. */
        if (!block_take(rx, rec_at(rx, rx->rec_ready)->tag)) {
            rx->overruns++;
            head_over(rx, HEAD_DROP, now_us);
            return;
        }
        head_start(rx, FRAME_BLOCK, rx->hstart, rx->hsum);
        rx->hneed = FRAME_BLOCK_BYTES;
    } else if (pos + 1u == rx->hneed) {
        head_over(rx, (uint8_t)(s - rx->hsum) == b ? HEAD_GOOD : HEAD_BAD, now_us);
        return;
    }
    if (FRAME_RX_INNER)
        head_next(rx, (uint16_t)(pos + 1u));
}

/* ISR: byte q (b; the running sum before it, s) is an event: the head's, or the LEN or
 * checksum byte of a candidate inside it. Then the nearest next one. (The head alone,
 * FRAME_RX_INNER 0: every byte is looked at, as its offset says.) */
static void event(struct frame_rx *rx, uint16_t q, uint8_t b, uint8_t s, uint32_t now_us)
{
    if (!FRAME_RX_INNER) {
        head_event(rx, q, b, s, now_us);
        return;
    }
    if (q == rx->len_at)
        inner_len(rx, q, b);
    if (q == rx->chk_at)
        inner_chk(rx, q, b, s);
    if (q == rx->head_at)
        head_event(rx, q, b, s, now_us);
    if (!rx->in_frame)
        return;
    /* Distances from the next byte (one already handled is 0xFFFF away); a new head
     * may have come, but the next byte is the same. */
    uint16_t next = rx->head_at, p = rx->pos;
    if ((uint16_t)(rx->len_at - p) < (uint16_t)(next - p))
        next = rx->len_at;
    if ((uint16_t)(rx->chk_at - p) < (uint16_t)(next - p))
        next = rx->chk_at;
    rx->next_ev = next;
}

/* ISR: D5 5D: a candidate starts with the next byte. Inside the head it is a record of
 * where (the head's bytes are its bytes); otherwise it is the head, in a slot. */
static void candidate_start(struct frame_rx *rx)
{
    bool inner = rx->in_frame;
    if (!FRAME_RX_INNER && inner)
        return;
    uint8_t end = rx->rec_end, s = NO_SLOT;
    if ((uint8_t)(end - load_acquire(&rx->rec_tail)) < FRAME_RECORDS)
        s = inner ? 0u : slot_take(rx);
    if (s == NO_SLOT) {
        if (inner)
            rx->lost++; /* counted if the head fails: else it was payload */
        else
            rx->overruns++;
        return;
    }
    uint16_t at = rx->pos, len = (uint16_t)(at + 1u);
    *rec_at(rx, end) = (struct frame_rec){at, s, rx->sum};
    rx->rec_end = (uint8_t)(end + 1u);
    if (inner) {
        rx->len_at = len;
        if ((uint16_t)(len - at) < (uint16_t)(rx->next_ev - at))
            rx->next_ev = len;
        return;
    }
    rx->hbuf = buf_of(rx, s);
    rx->hstart = at;
    rx->hsum = rx->sum;
    rx->hneed = NONE;
    if (FRAME_RX_INNER) {
        rx->head_at = len;
        rx->next_ev = len;
        rx->len_at = (uint16_t)(at - 1u); /* none: a byte that is past */
        rx->chk_at = rx->len_at;
    }
    rx->in_frame = 1;
}

void frame_rx_byte(struct frame_rx *rx, uint8_t b, uint32_t now_us)
{
    if ((int32_t)(now_us - rx->last_us) > (int32_t)rx->quiet_us) { /* gap_passed() */
        if (rx->in_frame)
            head_over(rx, HEAD_DROP, now_us);
        rx->prev = 0; /* a header cannot straddle a gap */
    }
    rx->last_us = now_us;
    if (rx->in_frame) {
        uint16_t q = rx->pos;
        uint8_t s = rx->sum;
        rx->hbuf[(uint16_t)(q - rx->hstart)] = b;
        rx->pos = (uint16_t)(q + 1u);
        rx->sum = (uint8_t)(s + b);
        if (!FRAME_RX_INNER || q == rx->next_ev)
            event(rx, q, b, s, now_us);
    }
    /* After the head's byte: a header ending on the last byte of a head that failed
     * starts the next; not on a good one's, the head's or one inside it (head_over() or
     * inner_chk() cleared prev, the byte before this one): that D5 5D was its payload
     * and checksum. One starting on its checksum byte may be real (the byte the checksum
     * stood in for was lost), so prev is this byte after. Read once, here: a flag kept
     * across the event cost 4 instructions on every byte (qemu_cost.py). */
    uint8_t prev = rx->prev;
    rx->prev = b;
    if (prev == PROTO_HEADER0 && b == PROTO_HEADER1)
        candidate_start(rx);
}

bool frame_rx_idle(struct frame_rx *rx, uint32_t now_us)
{
    if (rx->in_frame && gap_passed(rx, now_us)) {
        head_over(rx, HEAD_DROP, now_us);
        rx->prev = 0;
    }
    return !rx->in_frame;
}

bool frame_rx_quiet(struct frame_rx *rx, uint32_t now_us)
{
    if (!frame_rx_idle(rx, now_us))
        return false;
    /* Found rested since the last byte: still so, however long ago (gap_passed() is a
     * signed test, false again once 2^31 us have passed). */
    if (rx->quiet_seen && rx->quiet_last == rx->last_us)
        return true;
    if (!gap_passed(rx, now_us))
        return false;
    rx->quiet_last = rx->last_us;
    rx->quiet_seen = 1;
    return true;
}

void frame_rx_set_baud(struct frame_rx *rx, uint32_t baud)
{
    rx->gap_us = frame_rx_gap_us(baud);
    rx->byte_us = (10u * 1000000u + baud - 1u) / baud;
    rx->quiet_us = rx->gap_us + rx->byte_us;
}

const struct frame *frame_rx_peek(struct frame_rx *rx)
{
    uint8_t tail = rx->rec_tail;
    if (tail == load_acquire(&rx->rec_ready))
        return NULL;
    struct frame_rec r = *rec_at(rx, tail);
    uint8_t s = r.tag & TAG_BUF;
    struct frame *f = &rx->view;
    f->buf = buf_of(rx, s) + r.at;
    f->len = s == FRAME_BLOCK && r.at == 0 ? FRAME_BLOCK_BYTES : (uint16_t)(f->buf[1] + 2u);
    f->status = r.tag & TAG_BAD ? FRAME_BAD_CHECKSUM : FRAME_OK;
    f->end_us = rx->end_us[s];
    return f;
}

void frame_rx_release(struct frame_rx *rx)
{
    uint8_t tail = rx->rec_tail;
    uint8_t tag = rec_at(rx, tail)->tag, s = tag & TAG_BUF;
    store_release(&rx->rec_tail, (uint8_t)(tail + 1u)); /* the ISR may reuse it now */
    if (!(tag & TAG_LAST))
        return;
    uint8_t head = rx->free_head;
    rx->free_ring[head & MASK] = s == FRAME_BLOCK ? rx->block_slot : s;
    store_release(&rx->free_head, (uint8_t)(head + 1u));
    if (s == FRAME_BLOCK)
        store_release(&rx->block_busy, 0); /* the other slots were free all along */
}
