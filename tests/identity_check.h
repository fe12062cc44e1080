/* identity_check.h - shared by the fuzz harness and the corruption test: do the identity
 * registers (read-only, EEPROM: model number, firmware version) of a servo still hold
 * what they held at power-up (factory)? Traffic of any kind must never change them. */
#ifndef IDENTITY_CHECK_H
#define IDENTITY_CHECK_H

#include <stdbool.h>
#include <string.h>

#include "servo.h"

static inline bool identity_unchanged(const struct servo *s, const uint8_t *factory)
{
    for (uint8_t a = 0; a < REGS_SIZE; a++) {
        const struct reg_desc *d = &regs_table[a];
        if (d->size && regs_applicable(s->board, a) && d->access == REG_ACCESS_R &&
            d->area == REG_AREA_EE && memcmp(&s->regs.mem[a], &factory[a], d->size) != 0)
            return false;
    }
    return true;
}

#endif
