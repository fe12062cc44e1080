/* dispatch.h - the instruction dispatcher (PROTOCOL.md §3.2, §4): one table of the
 * instructions, each with its parameter lengths and the rules dispatch checks once before
 * its handler runs (in the style of Klipper's DECL_COMMAND and its HF_IN_SHUTDOWN flag).
 * The SDK's instruction codes, ERR bits and the set that spends commits are generated from
 * this table (tools/regdoc.c --protocol-json), and CTest fails when they drift.
 * Main loop only. */
#ifndef DISPATCH_H
#define DISPATCH_H

#include <stdbool.h>
#include <stdint.h>

#include "frame_rx.h"
#include "regs.h"

struct servo;

/* Rules of an instruction, checked by dispatch_frame() before the handler. */
#define INS_ANSWER_LEVEL1 0x01u  /* answered at status return level 1 too (READ), §3.2 */
#define INS_ANSWER_ALWAYS 0x02u  /* answered at every level and to broadcast (PING), §4.1 */
#define INS_IN_UPDATE 0x04u      /* executed while a §10 update session runs */
#define INS_MOVES 0x08u          /* starts motion: refused (instruction error) while braked,
                                  * asleep or unloaded, or on a motor with photo switches
                                  * before homing; a speed of 0 (rule 3) always passes */
#define INS_COMMITS 0x10u        /* may change an EEPROM register: spends the commit budget */
#define INS_BROADCAST_ONLY 0x20u /* addressed to one ID: instruction error (SYNC WRITE) */
#define INS_OWN_ANSWER 0x40u     /* once its rules pass, it answers by itself, at its own ID
                                  * and time, or not at all: dispatch schedules nothing */

/* An instruction's outcome: per-packet ERR bits and the answer's parameters. A handler
 * that answers by itself (INS_OWN_ANSWER) reads the frame's end and addressing here. */
struct dispatch_result {
    uint8_t err;
    uint8_t n;
    uint8_t own_answer; /* the entry that ran has INS_OWN_ANSWER (set by dispatch) */
    bool broadcast;
    uint32_t end_us;
    uint8_t data[REGS_SIZE];
};

/* One instruction (§4), or one sub-command of CUSTOM (§4.8): its rules. Its handler is
 * named beside it in the one list in dispatch.c (INSTRUCTIONS, CUSTOM_SUBS). */
struct instruction {
    uint8_t code;       /* instruction byte, or the CUSTOM sub-command */
    uint8_t flags;      /* INS_ rules */
    uint8_t min_n;      /* parameter bytes (after the sub-command for CUSTOM) */
    uint8_t max_n;
    uint8_t speed_at;   /* INS_MOVES: offset of a speed parameter whose 0 stops, or 0xFF */
#if REGS_WITH_TEXT
    const char *name;   /* as the SDK spells it */
#endif
};

/* The instruction table and CUSTOM's sub-commands, for the generated SDK copy and tests.
 * The §10 update sub-commands (0xFC, 0xFE) are frames of their own (update.h). */
/* cppcheck-suppress misra-c2012-8.11 ; the size is the list's, in dispatch.c (docs/lint.md) */
extern const struct instruction dispatch_instructions[];
extern const uint8_t dispatch_instruction_count;
/* cppcheck-suppress misra-c2012-8.11 ; the size is the list's, in dispatch.c (docs/lint.md) */
extern const struct instruction dispatch_custom[];
extern const uint8_t dispatch_custom_count;

/* Execute one received frame and schedule its answer, if it gets one. */
void dispatch_frame(struct servo *s, const struct frame *f);

/* RESET (§4.5): factory table, motion stopped, held write and trajectory dropped. */
void dispatch_factory_reset(struct servo *s);

#endif
