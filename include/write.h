/* write.h - a host's write of registers (WRITE, ACTION, SYNC WRITE): validated by the
 * table (regs.h), vetoed or accepted by the modules that act on the registers it touches,
 * stored all or nothing, then acted on. Each module registers the addresses it acts on in
 * one table of hooks (src/write.c), in the style of TinyUSB's class-driver table in
 * src/device/usbd.c, and each hook is handed its own module's part of the servo:
 *
 *   link    3 4 5 16 18 20  the settings in force and the RS485 terminator, once the
 *                           answer to the write has left the wire (§1)
 *   safety  25              clear a latched unload (refused while its cause lasts)
 *   motion  6-9 13 19 21 22 24 30 32 34 35 43 47
 *                           limits, resolution, zero side, ramps, homing, goal, speed,
 *                           brake, sleep: what they mean to the motor (command.c)
 *
 * The store acts on every EEPROM register whatever changed it (regs_set() marks it, the
 * main loop commits). Registers that act when they are next used are read there (11, 12,
 * 17, 18 by safety every tick; 49 when a move starts); tools/regdoc.c names each
 * register's effect from this table. Main loop only. */
#ifndef WRITE_H
#define WRITE_H

#include <stdint.h>

#include "regs.h"

struct servo;

_Static_assert(REGS_SIZE <= 64u, "a hook's acts_on and reads are 64-bit masks of addresses");

/* One module's part in register writes, as the docs and the tests see it; its check and
 * act functions are named beside it in the one list in write.c (HOOKS). */
struct write_hook {
    uint64_t acts_on; /* bit a: the module acts when register a is written */
#if REGS_WITH_TEXT
    const char *owner;
    uint64_t reads;   /* bit a: the module reads register a as it works */
    const char *effect;
#endif
};

/* cppcheck-suppress misra-c2012-8.11 ; the size is the list's, in write.c (docs/lint.md) */
extern const struct write_hook write_hooks[];
extern const uint8_t write_hook_count;

/* Apply a host write of n bytes at addr (§4.3): whole registers, writable, in range,
 * CW limit <= CCW limit, allowed by every module that acts on it; a goal clamped to the
 * limits. Returns 0 or ERR_INSTRUCTION; nothing is changed on error. */
uint8_t write_registers(struct servo *s, uint8_t addr, const uint8_t *data, uint8_t n);

#endif
