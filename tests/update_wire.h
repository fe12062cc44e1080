/* update_wire.h - the §10 frames (PROTOCOL.md §10) as a host sends them, byte for byte:
 * the one builder test_boot.c and test_update.c share. Each writes the frame into out and
 * returns its length; out must hold FRAME_BLOCK_BYTES + 4 bytes for a data block. */
#ifndef UPDATE_WIRE_H
#define UPDATE_WIRE_H

#include <stdint.h>
#include <string.h>

#include "crc.h"
#include "proto.h"

/* D5 5D id LEN body CHK, LEN = len_byte (the real length, or 0xFF for a data block). */
static inline uint16_t wire_frame(uint8_t *out, uint8_t id, uint8_t len_byte,
                                  const uint8_t *body, uint16_t n)
{
    out[0] = PROTO_HEADER0;
    out[1] = PROTO_HEADER1;
    out[2] = id;
    out[3] = len_byte;
    memcpy(&out[4], body, n);
    out[4u + n] = proto_sum(&out[2], (uint16_t)(n + 2u));
    return (uint16_t)(n + 5u);
}

static inline uint16_t enter_frame(uint8_t *out, uint8_t id)
{
    static const uint8_t body[] = {0xFF, PROTO_UPDATE_SUB_ENTER};
    return wire_frame(out, id, 3, body, sizeof body);
}

static inline uint16_t eof_frame(uint8_t *out, uint8_t id)
{
    static const uint8_t body[] = {0xFF, PROTO_UPDATE_SUB_BLOCK, PROTO_UPDATE_TYPE_EOF};
    return wire_frame(out, id, 4, body, sizeof body);
}

/* Header (type 1, data = 128 bytes) or data block (type 2, 1024 bytes) number num. */
static inline uint16_t block_frame(uint8_t *out, uint8_t id, uint8_t type, uint8_t num,
                                   const uint8_t *data)
{
    static uint8_t body[5u + PROTO_UPDATE_BLOCK_DATA + 2u];
    uint16_t n =
        type == PROTO_UPDATE_TYPE_DATA ? PROTO_UPDATE_BLOCK_DATA : PROTO_UPDATE_HEADER_DATA;
    body[0] = 0xFF;
    body[1] = PROTO_UPDATE_SUB_BLOCK;
    body[2] = type;
    body[3] = num;
    body[4] = (uint8_t)~num;
    memcpy(&body[5], data, n);
    uint16_t crc = crc16_update(0, data, n);
    body[5u + n] = (uint8_t)(crc >> 8);
    body[6u + n] = (uint8_t)crc;
    uint16_t total = (uint16_t)(n + 7u);
    return wire_frame(out, id, type == PROTO_UPDATE_TYPE_DATA ? 0xFFu : (uint8_t)(total + 1u),
                      body, total);
}

static inline uint16_t header_frame(uint8_t *out, uint8_t id, uint32_t length)
{
    uint8_t d[PROTO_UPDATE_HEADER_DATA] = {(uint8_t)(length >> 24), (uint8_t)(length >> 16),
                                           (uint8_t)(length >> 8), (uint8_t)length};
    return block_frame(out, id, PROTO_UPDATE_TYPE_HEADER, 0, d);
}

/* The header with length 0: the end of the batch. */
static inline uint16_t batch_end_frame(uint8_t *out, uint8_t id)
{
    static const uint8_t zero[PROTO_UPDATE_HEADER_DATA];
    return block_frame(out, id, PROTO_UPDATE_TYPE_HEADER, 0, zero);
}

/* Data block num (1-based) of img, the last one padded with 0xFF. */
static inline uint16_t data_frame(uint8_t *out, uint8_t id, const uint8_t *img, uint32_t len,
                                  uint8_t num)
{
    uint8_t d[PROTO_UPDATE_BLOCK_DATA];
    uint32_t at = (uint32_t)(num - 1u) * PROTO_UPDATE_BLOCK_DATA;
    memset(d, 0xFF, sizeof d);
    if (at < len)
        memcpy(d, &img[at],
               len - at < PROTO_UPDATE_BLOCK_DATA ? len - at : PROTO_UPDATE_BLOCK_DATA);
    return block_frame(out, id, PROTO_UPDATE_TYPE_DATA, num, d);
}

static inline uint8_t blocks_of(uint32_t len)
{
    return (uint8_t)((len + PROTO_UPDATE_BLOCK_DATA - 1u) / PROTO_UPDATE_BLOCK_DATA);
}

#endif
