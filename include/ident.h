/* ident.h - every servo addressed by its unique identity, duplicates and factory-fresh
 * servos included (issue 27; the wire format is in docs/decisions.md, "Identity"):
 * CUSTOM sub-command 0x11, outside the vendor's subs (0x01, 0x02, 0xFC, 0xFE).
 *
 *   D5 5D id LEN FF 11 op params CHK     LEN = 4 + params (INS, sub, op and CHK)
 *
 *   op 0x01 ENUMERATE   k prefix         broadcast only. A servo whose UID's first k
 *                                        nibbles (nibble i: byte i/2, low nibble first)
 *                                        equal the prefix (ceil(k/2) bytes, 0 <= k <= 23)
 *                                        answers in slot s, its nibble k (16 slots).
 *   op 0x02 IDENTIFY                     addressed to its ID: it answers.
 *   op 0x02 IDENTIFY    uid[12]          at its ID or broadcast: the servo with uid answers.
 *   op 0x03 SET ID      uid[12] id       at its ID or broadcast: the servo with uid takes
 *                                        the ID (a WRITE of register 3, kept in flash); it
 *                                        answers unless broadcast.
 *
 * Every answer, to any op, is one shape, sent at ID byte 0xFF (no servo executes it, and
 * a host tells it from a status packet of ID 0xFF, which no servo has):
 *   D5 5D FF 20 ERR op uid[12] id variant model_L model_H baud ~uid[12] CHK  (36 bytes)
 * It starts IDENT_TURNAROUND_US after the request's end (register 5 aside: slots of
 * servos at different IDs line up), ENUMERATE's slot s ident_slot_us() later. Two answers
 * in one slot overlap bit for bit on an RS485 bus with fail-safe bias (the line is the AND
 * of the talkers): uid & ~uid of the result is nonzero only for a single talker, and the
 * first UID bit where both copies read 0 is where the talkers differ.
 * It is an entry of CUSTOM's sub-command table (src/dispatch.c, INS_OWN_ANSWER): the
 * table's rules come first, so sub 0x11 without an op, or during a §10 update session, is
 * an instruction error as any other (§4.8); a malformed op, or a UID not this servo's,
 * gets no answer. Main loop only; never in update mode (the loader takes §10 frames only). */
#ifndef IDENT_H
#define IDENT_H

#include <stdbool.h>
#include <stdint.h>

struct servo;

#define IDENT_SUB 0x11u
#define IDENT_ENUMERATE 0x01u
#define IDENT_IDENTIFY 0x02u
#define IDENT_SET_ID 0x03u
#define IDENT_UID_BYTES 12u
#define IDENT_ANSWER_DATA (6u + 2u * IDENT_UID_BYTES)
#define IDENT_ANSWER_BYTES (6u + IDENT_ANSWER_DATA)
#define IDENT_TURNAROUND_US 500u
#define IDENT_GUARD_US 100u /* per slot, for the talkers' clocks and polling */

/* An ENUMERATE answer slot at baud: the answer, four byte-times and the guard. */
uint32_t ident_slot_us(uint32_t baud);

/* A CUSTOM frame with sub-command 0x11: p the bytes after the sub (op, params), n of
 * them (>= 1), broadcast or addressed to this servo, the frame ended at end_us. */
void ident_frame(struct servo *s, const uint8_t *p, uint8_t n, bool broadcast,
                 uint32_t end_us);

#endif
