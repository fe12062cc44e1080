/* proto.h - wire constants of the servo bus (PROTOCOL.md §2-§4) and the status packet
 * builder. Pure functions, no state. */
#ifndef PROTO_H
#define PROTO_H

#include <stdbool.h>
#include <stdint.h>

#include "regs.h"

#define PROTO_HEADER0 0xD5u
#define PROTO_HEADER1 0x5Du
#define PROTO_ID_BROADCAST 0xFEu
#define PROTO_ID_MAX 0xFDu /* highest ID of one servo */
#define PROTO_ID_INVALID 0xFFu
#define PROTO_LEN_MAX 255u                   /* LEN counts INS (or ERR), params and CHK */
#define PROTO_PARAMS_MAX (PROTO_LEN_MAX - 2u) /* so a packet's parameters: at most 253 */

/* Instructions (§4). */
#define INS_PING 0x01u
#define INS_READ 0x02u
#define INS_WRITE 0x03u
#define INS_REG_WRITE 0x04u
#define INS_ACTION 0x05u
#define INS_RESET 0x06u
#define INS_START_END 0x07u
#define INS_TRAJ_WRITE 0x0Au
#define INS_TRAJ_ACTION 0x0Bu
#define INS_SYNC_WRITE 0x83u
#define INS_CUSTOM 0xFFu

/* ERR byte bits (§3.1). */
#define ERR_OVER_TEMPERATURE 0x01u
#define ERR_OVER_CURRENT 0x02u
#define ERR_OVER_VOLTAGE 0x04u
#define ERR_UNDER_VOLTAGE 0x08u
#define ERR_CHECKSUM 0x10u
#define ERR_INSTRUCTION 0x20u
#define ERR_STALL 0x40u

/* Longest status packet: header, ID, LEN, ERR, a READ of the whole table, checksum. */
#define PROTO_STATUS_MAX (6u + REGS_SIZE)
_Static_assert(REGS_SIZE <= PROTO_PARAMS_MAX, "an answer's LEN counts a READ of the whole table");

/* The §10 update frames, shared by the receiver (the data block is the one frame longer
 * than LEN can say) and the update session: CUSTOM with sub-command 0xFC (enter) or 0xFE
 * (a block: header, data or end of file). */
#define PROTO_UPDATE_SUB_ENTER 0xFCu
#define PROTO_UPDATE_SUB_BLOCK 0xFEu
#define PROTO_UPDATE_TYPE_HEADER 0x01u
#define PROTO_UPDATE_TYPE_DATA 0x02u
#define PROTO_UPDATE_TYPE_EOF 0x04u
#define PROTO_UPDATE_HEADER_DATA 128u
#define PROTO_UPDATE_BLOCK_DATA 1024u
/* A data block, header stripped: ID LEN(FF) FF FE 02 n ~n, the data, CRC-16, CHK. */
#define PROTO_UPDATE_DATA_FRAME (7u + PROTO_UPDATE_BLOCK_DATA + 3u)

/* Speeds (register 32, CUSTOM MOVE, §5): bit 15 the direction, bits 0-14 the magnitude. */
#define PROTO_SPEED_MAGNITUDE 0x7FFFu
#define PROTO_SPEED_REVERSE 0x8000u

/* The angle limits (registers 9-12) and the positions they bound: 0..0x7FFF units. */
#define PROTO_LIMIT_MAX 0x7FFF

/* Rule 3 of §0: a speed whose magnitude is 0 stops the motor, whatever its direction bit. */
bool proto_speed_is_stop(uint16_t speed);

/* Little-endian 16-bit value at p (§4: multi-byte values are L then H). */
uint16_t proto_get16(const uint8_t *p);

/* The same for a little-endian 32-bit value. */
uint32_t proto_get32(const uint8_t *p);

/* Plain 8-bit sum of n bytes (§2: not inverted). */
uint8_t proto_sum(const uint8_t *p, uint16_t n);

/* Write `D5 5D id LEN first data... CHK` into out (n + 6 bytes, n <= 253) and return its
 * length. Instruction packets (first = INS) and status packets (first = ERR) share this
 * shape (§2, §3). */
uint16_t proto_build_packet(uint8_t *out, uint8_t id, uint8_t first, const uint8_t *data,
                            uint8_t n);

#endif
