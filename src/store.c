/* store.c - power-loss-safe emulated EEPROM on flash pages (layout in store.h). */
#include <string.h>

#include "clock.h"
#include "crc.h"
#include "hal.h"
#include "proto.h"
#include "store.h"

#define MAGIC 0x5E3Eu
#define OFF_SEQ 2u
#define OFF_CRC 6u
#define OFF_COMMIT 10u
_Static_assert(OFF_SEQ == 2u && OFF_CRC == 6u, "compact(): the header's half-words in a row");
_Static_assert(STORE_HEADER_BYTES == OFF_COMMIT + 2u, "the header ends with the commit mark");
#define COMMITTED 0x0000u
#define ERASED 0xFFFFu

/* Record tag: a fixed pattern in bits 0-5 tells a record from noise. */
#define TAG_PATTERN 0x2Au
#define TAG_FIRST 0x80u /* first record of a group */
#define TAG_LAST 0x40u  /* last record of a group */

static uint16_t half_at(const uint8_t *page, uint16_t off)
{
    return proto_get16(&page[off]);
}

static uint32_t header_crc(uint32_t seq)
{
    /* Little-endian (regs.h: the targets are): MAGIC then seq copied from two words,
     * not six byte stores. */
    const uint32_t words[2] = {MAGIC, seq};
    uint8_t bytes[6];
    __builtin_memcpy(bytes, words, 2);
    __builtin_memcpy(&bytes[2], &words[1], 4);
    return ~crc32_update(CRC32_INIT, bytes, sizeof bytes);
}

/* Record check: CRC-16/CCITT of tag|addr, value and the page's sequence number, with
 * 0xFFFF (an unwritten half-word) mapped away so it never matches. */
static uint16_t record_check(uint16_t head, uint16_t value, uint32_t seq)
{
    /* Little-endian, as header_crc: two words, not eight byte stores. */
    const uint32_t words[2] = {head | ((uint32_t)value << 16), seq};
    uint8_t bytes[8];
    __builtin_memcpy(bytes, words, sizeof bytes);
    uint16_t crc = crc16_update(0xFFFFu, bytes, sizeof bytes);
    return crc == ERASED ? 0x7FFFu : crc;
}

/* The registers the store keeps: writable EEPROM registers of this variant. (Model
 * number and firmware version come from the build, not from flash.) */
static bool stored(const struct board *b, uint8_t addr)
{
    return regs_applicable(b, addr) && regs_table[addr].area == REG_AREA_EE &&
           (regs_table[addr].access & REG_ACCESS_W);
}

/* Does the page carry a valid header and a complete image? Then its sequence number. */
static bool page_committed(const uint8_t *page, uint32_t *seq)
{
    uint32_t s = half_at(page, OFF_SEQ) | ((uint32_t)half_at(page, OFF_SEQ + 2u) << 16);
    uint32_t crc = half_at(page, OFF_CRC) | ((uint32_t)half_at(page, OFF_CRC + 2u) << 16);
    if (half_at(page, 0) != MAGIC || crc != header_crc(s) ||
        half_at(page, OFF_COMMIT) != COMMITTED)
        return false;
    *seq = s;
    return true;
}

static bool page_blank(const uint8_t *page)
{
    for (uint16_t i = 0; i < HAL_FLASH_PAGE_BYTES; i++)
        if (page[i] != 0xFFu)
            return false;
    return true;
}

static bool slot_blank(const uint8_t *page, uint16_t off)
{
    return half_at(page, off) == ERASED && half_at(page, off + 2u) == ERASED &&
           half_at(page, off + 4u) == ERASED;
}

/* Read the records of a committed page: complete groups only, in order, each address
 * keeping the last value a complete group gave it. Returns the offset of the first
 * blank slot (where the next record goes). Table-free: the bootloader uses it alone.
 * A group is applied once its last record is read, from its first one on: every record
 * between them is valid (a torn one ends the group), so no copy of *v is needed (a
 * struct store_values less on the stack of power-up). */
_Static_assert(STORE_HEADER_BYTES > 0u, "scan: offset 0 is never a record");
static uint16_t scan(const uint8_t *page, uint32_t seq, struct store_values *v)
{
    uint16_t first = 0; /* the open group's first record; 0: none (the header is there) */
    uint16_t off = STORE_HEADER_BYTES;
    for (; off + STORE_RECORD_BYTES <= HAL_FLASH_PAGE_BYTES; off += STORE_RECORD_BYTES) {
        if (slot_blank(page, off))
            break;
        uint16_t head = half_at(page, off), value = half_at(page, off + 2u);
        uint8_t tag = (uint8_t)(head >> 8), addr = (uint8_t)head;
        bool valid = half_at(page, off + 4u) == record_check(head, value, seq) &&
                     (tag & 0x3Fu) == TAG_PATTERN && addr < REGS_SIZE;
        if (!valid) {
            first = 0; /* a torn record ends the group it was in: dropped */
            continue;
        }
        if (tag & TAG_FIRST)
            first = off; /* a group left open before it is dropped */
        if (first && (tag & TAG_LAST)) { /* else the rest of a group whose start was lost */
            for (uint16_t at = first; at <= off; at += STORE_RECORD_BYTES) {
                uint8_t a = page[at]; /* the head's low byte (little-endian): the address */
                v->value[a] = half_at(page, at + 2u);
                v->found |= (uint64_t)1u << a;
            }
            first = 0;
        }
    }
    return off;
}

/* The committed page with the newest sequence number, or STORE_NO_PAGE. */
static uint8_t newest_page(struct hal *hal, uint32_t *seq)
{
    uint8_t active = STORE_NO_PAGE;
    for (uint8_t p = 0; p < HAL_FLASH_PAGES; p++) {
        uint32_t s;
        if (page_committed(hal_flash_page(hal, p), &s) &&
            (active == STORE_NO_PAGE || (int32_t)(s - *seq) > 0)) {
            active = p;
            *seq = s;
        }
    }
    return active;
}

void store_read(struct hal *hal, struct store_values *out)
{
    uint32_t seq = 0;
    uint8_t p = newest_page(hal, &seq);
    out->found = 0;
    if (p != STORE_NO_PAGE)
        (void)scan(hal_flash_page(hal, p), seq, out);
}

/* The page after the active one in rotation: where the next compaction goes. Not
 * inlined: one copy of the modulo for its three callers (8 B). */
__attribute__((noinline)) static uint8_t spare_page(const struct store *st)
{
    return st->active == STORE_NO_PAGE ? 0u : (uint8_t)((st->active + 1u) % HAL_FLASH_PAGES);
}

/* Not inlined: at power-up only, and its two copies of struct store_values (216 B) would
 * otherwise sit in the frame of the main loop it is inlined into under -flto, under every
 * call the loop makes for ever (the worst-case stack of make firmware). */
__attribute__((noinline)) void store_load(struct store *st, struct hal *hal, struct regs *r,
                                          uint32_t now_us)
{
    memset(st, 0, sizeof *st);
    st->hal = hal;
    st->tokens = STORE_BURST;
    st->refill_us = STORE_REFILL_US;
    st->token_at = now_us;
    struct store_values v = {0};
    st->active = newest_page(hal, &st->seq);
    if (st->active != STORE_NO_PAGE)
        st->next = scan(hal_flash_page(hal, st->active), st->seq, &v);
    /* Only the registers this variant keeps count. A stored value out of its register's
     * range (a foreign or corrupt image) stays at the factory value; so do both limits
     * if they would cross. */
    uint64_t found = v.found; /* bit a in bit 0 at address a: a shift by one a step */
    for (uint8_t a = 0; a < REGS_SIZE; a++, found >>= 1)
        if (stored(r->board, a) && (found & 1u) && regs_in_range(a, v.value[a]))
            regs_set(r, a, v.value[a]);
    if (regs_get(r, REG_CW_LIMIT) > regs_get(r, REG_CCW_LIMIT)) {
        regs_set(r, REG_CW_LIMIT, regs_default(r->board, REG_CW_LIMIT));
        regs_set(r, REG_CCW_LIMIT, regs_default(r->board, REG_CCW_LIMIT));
    }
    memcpy(st->saved, r->mem, sizeof st->saved);
    (void)regs_take_ee_changed(r); /* the table is what the flash holds */
    st->spare_blank = page_blank(hal_flash_page(hal, spare_page(st)));
}

static bool program(struct store *st, uint8_t p, uint16_t off, uint16_t v)
{
    if (hal_flash_program(st->hal, p, off, v))
        return true;
    st->faults++;
    return false;
}

static bool write_record(struct store *st, uint8_t p, uint16_t off, uint8_t tag, uint8_t addr,
                         const uint8_t *mem, uint32_t seq)
{
    uint16_t head = (uint16_t)(((TAG_PATTERN | tag) << 8) | addr);
    uint16_t value = regs_value(&mem[addr], regs_table[addr].size);
    const uint16_t half[3] = {head, value, record_check(head, value, seq)};
    for (uint16_t i = 0; i < 3u; i++) /* in order, the first failure ending it */
        if (!program(st, p, (uint16_t)(off + 2u * i), half[i]))
            return false;
    return true;
}

/* Addresses of the registers in [from, REGS_SIZE) that the store keeps and that differ
 * between x and y (all of them when y is NULL): the next one, or REGS_SIZE. */
static uint8_t next_reg(const struct board *b, const uint8_t *x, const uint8_t *y, uint8_t from)
{
    for (uint8_t a = from; a < REGS_SIZE; a++)
        if (stored(b, a) && (!y || x[a] != y[a] || (regs_table[a].size > 1u && x[a + 1] != y[a + 1])))
            return a;
    return REGS_SIZE;
}

/* Write the registers next_reg() names (against saved, or all when it is NULL) as one
 * group of records on page p from *off on, advancing *off past each slot written (a torn
 * slot is skipped, not reused). */
static bool write_group(struct store *st, uint8_t p, uint16_t *off, const struct regs *r,
                        const uint8_t *saved, uint32_t seq)
{
    uint8_t tag = TAG_FIRST;
    for (uint8_t a = next_reg(r->board, r->mem, saved, 0); a < REGS_SIZE;) {
        uint8_t after = next_reg(r->board, r->mem, saved, (uint8_t)(a + regs_table[a].size));
        bool ok = write_record(st, p, *off, (uint8_t)(tag | (after == REGS_SIZE ? TAG_LAST : 0u)),
                               a, r->mem, seq);
        *off = (uint16_t)(*off + STORE_RECORD_BYTES);
        if (!ok)
            return false;
        tag = 0;
        a = after;
    }
    return true;
}

/* Write the whole image to the next page in rotation; it takes over once committed. */
static bool compact(struct store *st, const struct regs *r)
{
    uint8_t p = spare_page(st);
    const uint8_t *page = hal_flash_page(st->hal, p);
    if (!st->spare_blank || !page_blank(page)) {
        if (!hal_flash_erase(st->hal, p) || !page_blank(page)) {
            st->faults++;
            st->spare_blank = 0;
            return false;
        }
    }
    st->spare_blank = 0;
    uint32_t seq = st->seq + 1u, crc = header_crc(seq);
    /* The header's half-words in order, the first failure ending it: one call in a loop
     * rather than five (smaller). */
    const uint16_t header[5] = {MAGIC, (uint16_t)seq, (uint16_t)(seq >> 16), (uint16_t)crc,
                                (uint16_t)(crc >> 16)};
    for (uint16_t i = 0; i < 5u; i++)
        if (!program(st, p, (uint16_t)(2u * i), header[i]))
            return false;
    uint16_t off = STORE_HEADER_BYTES;
    if (!write_group(st, p, &off, r, NULL, seq) ||
        !program(st, p, OFF_COMMIT, COMMITTED)) /* the new page counts from here */
        return false;
    st->active = p;
    st->seq = seq;
    st->next = off;
    return true;
}

/* Append the changed registers as one group, or compact if the page cannot hold it. */
static bool commit(struct store *st, const struct regs *r)
{
    uint8_t count = 0;
    for (uint8_t a = next_reg(r->board, r->mem, st->saved, 0); a < REGS_SIZE;
         a = next_reg(r->board, r->mem, st->saved, (uint8_t)(a + regs_table[a].size)))
        count++;
    if (count == 0u)
        return true;
    uint32_t room = (HAL_FLASH_PAGE_BYTES - st->next) / STORE_RECORD_BYTES;
    if (st->active == STORE_NO_PAGE || count > room)
        return compact(st, r);
    return write_group(st, st->active, &st->next, r, st->saved, st->seq);
}

/* Rate limit (see docs/persistence.md): may a commit happen now? Tokens refill one per
 * refill_us up to STORE_BURST. store_poll() calls this every main-loop pass, so the time
 * since token_at never reaches the clock's wrap: a full bucket moves token_at along, and
 * a refilling one is at most STORE_BURST x 64 s (68 min) behind. */
static bool token_ready(struct store *st, uint32_t now_us)
{
    if (st->refill_us == 0u)
        return true;
    while (st->tokens < STORE_BURST && clock_since(now_us, st->token_at) >= st->refill_us) {
        st->tokens++;
        st->token_at += st->refill_us;
    }
    if (st->tokens == STORE_BURST)
        st->token_at = now_us;
    return st->tokens > 0u;
}

uint8_t store_tokens(const struct store *st)
{
    return st->tokens;
}

void store_defer(struct store *st)
{
    st->lazy = 1;
}

void store_sync(struct store *st, const struct regs *r, uint32_t now_us)
{
    if (!token_ready(st, now_us)) {
        st->pending = 1; /* whether anything changed is looked at when a commit may run */
        return;
    }
    if (next_reg(r->board, r->mem, st->saved, 0) == REGS_SIZE) {
        st->pending = 0;
        st->lazy = 0;
        return; /* nothing changed: no flash write */
    }
    if (st->refill_us)
        st->tokens--;
    if (commit(st, r)) {
        /* Whole registers: a 16-bit register's high byte has no table entry of its own
         * (size 0), and a copy refreshed byte by byte would differ forever (issue 19). */
        for (uint8_t a = 0; a < REGS_SIZE; a++)
            if (stored(r->board, a))
                memcpy(&st->saved[a], &r->mem[a], regs_table[a].size);
        st->pending = 0;
        st->lazy = 0; /* a waiting lazy change went with it */
    } else {
        st->pending = 1; /* retried by store_poll, into a fresh page */
        st->next = HAL_FLASH_PAGE_BYTES;
    }
}

void store_poll(struct store *st, const struct regs *r, uint32_t now_us, bool idle)
{
    bool full = token_ready(st, now_us) && st->tokens == STORE_BURST;
    if (st->pending || (st->lazy && idle && full))
        store_sync(st, r, now_us);
    /* A failed erase stalls the CPU for nothing: the next try waits a second. */
    if (!st->spare_blank && idle && (!st->retrying || clock_since(now_us, st->failed_at) >= 1000000u)) {
        uint8_t p = spare_page(st);
        const uint8_t *page = hal_flash_page(st->hal, p);
        st->retrying = 0;
        if (page_blank(page) || (hal_flash_erase(st->hal, p) && page_blank(page))) {
            st->spare_blank = 1;
        } else {
            st->faults++;
            st->retrying = 1;
            st->failed_at = now_us;
        }
    }
}

void store_flush(struct store *st, const struct regs *r, uint32_t now_us)
{
    (void)token_ready(st, now_us);
    if (st->tokens == 0u)
        st->tokens = 1;
    store_sync(st, r, now_us);
}
