/* store.h - the persistent store of the EEPROM registers (PROTOCOL.md §5.3): an emulated
 * EEPROM on HAL_FLASH_PAGES flash pages that survives a power cut at any instant.
 *
 * Layout of a page (half-words, little-endian):
 *   0: magic   2-4: sequence number (32-bit)   6-8: CRC-32 of magic and sequence
 *   10: commit mark (0x0000 once the page holds a complete image; erased = 0xFFFF)
 *   12...: records of 6 bytes: tag|addr, value, check (CRC-16 of tag|addr, value and the
 *          page's sequence number; never 0xFFFF, so an unwritten check never matches)
 * A host write that changes EEPROM registers is appended as one group of records (first
 * and last flagged); a group counts only when complete, so every write is all or
 * nothing. When a page is full the whole image is written to the next page in rotation,
 * which counts once its commit mark is written; the old page stays valid until then.
 * Recovery at boot only reads. See docs/persistence.md for the argument.
 *
 * Main loop only, and only servo_poll() calls it: every change of a stored register goes
 * through regs_set(), which marks the table; at the end of a main-loop pass in which the
 * table was marked, servo_poll() calls store_sync() (docs/persistence.md, "For host
 * tools", states what this guarantees a host). */
#ifndef STORE_H
#define STORE_H

#include <stdbool.h>
#include <stdint.h>

#include "hal.h"
#include "regs.h"

#define STORE_NO_PAGE 0xFFu
#define STORE_BURST 64u                  /* commits allowed back to back */
#define STORE_REFILL_US (64u * 1000000u) /* then one commit per 64 s (see persistence.md) */

struct store {
    struct hal *hal;
    uint8_t active;     /* page holding the committed state, or STORE_NO_PAGE */
    uint8_t spare_blank; /* the next page in rotation is known to be erased */
    uint16_t next;      /* offset of the first free record slot in the active page */
    uint32_t seq;       /* sequence number of the active page */
    uint8_t saved[REGS_SIZE]; /* EEPROM register values as the flash holds them */
    uint8_t pending;    /* the table differs from saved[] and waits for a commit */
    uint8_t tokens;     /* commits allowed now */
    uint32_t refill_us; /* one token per refill_us; 0 = no rate limit */
    uint32_t token_at;  /* when the last token was added (or the bucket was full) */
    uint32_t faults;    /* flash operations that failed */
    uint8_t retrying;   /* a pre-erase failed at failed_at: the next waits a second */
    uint8_t lazy;       /* a change that may wait for a full bucket and a resting motor */
    uint32_t failed_at;
};

/* What the flash holds, read without the register table (the bootloader's update mode
 * uses it alone, for ID, baud and return delay): the value each address last got from a
 * complete record group of the newest committed page; bit a of found is set when
 * address a has one. store_load() reads through the same code, then applies the table's
 * rules (registers this variant keeps, ranges). */
struct store_values {
    uint64_t found;
    uint16_t value[REGS_SIZE];
};
_Static_assert(REGS_SIZE <= 64u, "found is a 64-bit mask");

/* Read the store (no writes) into out. */
void store_read(struct hal *hal, struct store_values *out);

/* Boot: read the flash (no writes) and put every committed EEPROM value into r, which
 * holds the factory table. Registers with nothing valid stored keep their factory value. */
void store_load(struct store *st, struct hal *hal, struct regs *r, uint32_t now_us);

/* Make the flash hold r's EEPROM registers: one all-or-nothing commit of what changed,
 * none if nothing did (every register compared whole with what the flash holds). Past
 * the burst allowance commits are spaced refill_us apart; a change that has to wait stays
 * pending and store_poll() commits it. */
void store_sync(struct store *st, const struct regs *r, uint32_t now_us);

/* Main loop, every pass: refill the commit budget (so a refill after any idle saturates
 * rather than wrapping with the 32-bit clock); commit a pending change when allowed; when
 * the motor is idle, erase the next page in rotation ahead of time so a compaction never
 * has to (an erase stalls the CPU for tens of milliseconds), and commit a lazy change
 * (store_defer) if the budget is full. */
void store_poll(struct store *st, const struct regs *r, uint32_t now_us, bool idle);

/* A change of the table that may reach the flash late (CUSTOM MOVE's ramps on the base,
 * docs/persistence.md): it is committed with the next commit of anything else, or alone
 * by store_poll() once the motor rests and the budget is full, so ordinary driving never
 * spends the budget a host's settings rely on. */
void store_defer(struct store *st);

/* Commits allowed back to back now (the budget's bucket), for tests and host tools. */
uint8_t store_tokens(const struct store *st);

/* Commit whatever differs from the flash now, past the rate limit: the servo is about to
 * restart (a firmware update, once per update), and a waiting change must not be lost. */
void store_flush(struct store *st, const struct regs *r, uint32_t now_us);

/* Number of record slots in a page, for tests and benchmarks. */
#define STORE_HEADER_BYTES 12u
#define STORE_RECORD_BYTES 6u
#define STORE_SLOTS ((HAL_FLASH_PAGE_BYTES - STORE_HEADER_BYTES) / STORE_RECORD_BYTES)

#endif
