/* ident.c - the servo addressed by its unique identity (ident.h, docs/decisions.md):
 * ENUMERATE in UID-chosen slots, IDENTIFY and SET ID by UID. It keeps no state: a host
 * can drop a search at any point, and a servo that restarts mid-search loses nothing. */
#include <string.h>

#include "hal.h"
#include "ident.h"
#include "link.h"
#include "proto.h"
#include "servo.h"
#include "write.h"

uint32_t ident_slot_us(uint32_t baud)
{
    return link_bytes_us(baud, IDENT_ANSWER_BYTES + 4u) + IDENT_GUARD_US;
}

static void ident_answer(struct servo *s, uint8_t op, uint32_t at)
{
    const uint8_t *u = hal_uid(s->hal);
    const uint8_t *mem = s->regs.mem;
    uint8_t d[IDENT_ANSWER_DATA];
    d[0] = op;
    for (uint32_t i = 0; i < IDENT_UID_BYTES; i++) {
        d[1u + i] = u[i];
        d[18u + i] = (uint8_t)~u[i]; /* single talker: exactly the complement (ident.h) */
    }
    d[13] = mem[REG_ID]; /* a SET ID's new ID: in force once this answer is out */
    d[14] = servo_board(s)->variant;
    d[15] = mem[REG_MODEL_NUMBER];
    d[16] = mem[REG_MODEL_NUMBER + 1u];
    d[17] = mem[REG_BAUD_RATE];
    link_answer(s, PROTO_ID_INVALID, safety_err(&s->safety), d, sizeof d, at);
}

void ident_frame(struct servo *s, const uint8_t *p, uint8_t n, bool broadcast, uint32_t end_us)
{
    const uint8_t *u = hal_uid(s->hal);
    uint32_t at = end_us + IDENT_TURNAROUND_US;
    uint8_t op = p[0];
    if (op == IDENT_ENUMERATE) {
        /* UID nibble i: byte i / 2, low nibble first. On the STM32F1 the first bytes are
         * the die's X/Y position on its wafer, where servos of one batch differ first. */
        uint32_t k = p[n > 1u], at_byte = k >> 1; /* n == 1: k = op, refused below */
        if (!broadcast || k >= 2u * IDENT_UID_BYTES || n != 2u + (k + 1u) / 2u ||
            memcmp(u, &p[2], at_byte) != 0 || ((k & 1u) && ((u[at_byte] ^ p[2u + at_byte]) & 0x0Fu)))
            return; /* not under this prefix */
        uint32_t slot = (k & 1u) ? u[at_byte] >> 4 : u[at_byte] & 0x0Fu;
        ident_answer(s, op, at + slot * ident_slot_us(link_baud_in_force(&s->link)));
    } else if (op == IDENT_IDENTIFY && n == 1u) {
        if (!broadcast)
            ident_answer(s, op, at);
    } else if (n == 13u + (op == IDENT_SET_ID) && memcmp(&p[1], u, IDENT_UID_BYTES) == 0) {
        if (op == IDENT_IDENTIFY ||
            (op == IDENT_SET_ID && !write_registers(s, REG_ID, &p[13], 1) && !broadcast))
            ident_answer(s, op, at);
    }
}
