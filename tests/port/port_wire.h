/* port_wire.h - what the port tests put on the bus and in flash: application images
 * (image.h layout, stamped with the core's CRC-32) and the host's frames, the §10
 * update frames included (PROTOCOL.md §10, as tests/test_update.c builds them). */
#ifndef PORT_WIRE_H
#define PORT_WIRE_H

#include <stdint.h>
#include <string.h>

#include "crc.h"
#include "image.h"
#include "proto.h"

static inline void port_put32(uint8_t *p, uint32_t v)
{
    for (uint32_t i = 0; i < 4u; i++)
        p[i] = (uint8_t)(v >> (8u * i));
}

/* A valid application image of len bytes for model_number, seeded content; its vector table
 * starts with a stack pointer in RAM and a Thumb reset vector in the slot. */
static inline void port_image_build(uint8_t *img, uint32_t len, uint16_t model_number,
                                    uint8_t version, uint32_t seed)
{
    uint32_t x = seed * 2654435761u + 0x9E3779B9u;
    for (uint32_t i = 0; i < len; i++) {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        img[i] = (uint8_t)x;
    }
    port_put32(&img[0], 0x20001800u);
    port_put32(&img[4], 0x08002000u + 0x400u + (seed % 256u) * 4u + 1u);
    uint8_t *info = &img[IMAGE_INFO_OFFSET];
    port_put32(&info[IMAGE_OFF_MAGIC], IMAGE_MAGIC);
    port_put32(&info[IMAGE_OFF_LENGTH], len);
    port_put32(&info[IMAGE_OFF_CRC], 0);
    info[IMAGE_OFF_MODEL] = (uint8_t)model_number;
    info[IMAGE_OFF_MODEL + 1u] = (uint8_t)(model_number >> 8);
    info[IMAGE_OFF_VERSION] = version;
    info[IMAGE_OFF_RESERVED] = 0;
    port_put32(&info[IMAGE_OFF_CRC], ~crc32_update(CRC32_INIT, img, len));
}

/* D5 5D id LEN ins params CHK (LEN = n + 2). */
static inline uint16_t port_frame(uint8_t *out, uint8_t id, uint8_t ins, const uint8_t *p,
                                  uint8_t n)
{
    out[0] = PROTO_HEADER0;
    out[1] = PROTO_HEADER1;
    out[2] = id;
    out[3] = (uint8_t)(n + 2u);
    out[4] = ins;
    if (n)
        memcpy(&out[5], p, n);
    out[5u + n] = proto_sum(&out[2], (uint16_t)(n + 3u));
    return (uint16_t)(n + 6u);
}

/* §10: D5 5D id LEN body CHK, LEN the body's length + 1 (0xFF for a data block). */
static inline uint16_t port_update_frame(uint8_t *out, uint8_t id, uint8_t len_byte,
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

static inline uint16_t port_update_enter(uint8_t *out, uint8_t id)
{
    static const uint8_t body[] = {0xFF, PROTO_UPDATE_SUB_ENTER};
    return port_update_frame(out, id, 3, body, sizeof body);
}

static inline uint16_t port_update_eof(uint8_t *out, uint8_t id)
{
    static const uint8_t body[] = {0xFF, PROTO_UPDATE_SUB_BLOCK, PROTO_UPDATE_TYPE_EOF};
    return port_update_frame(out, id, 4, body, sizeof body);
}

/* Header (data = 128 bytes, the length first, big-endian; all zero: end of batch) or
 * data block num (1024 bytes), with its CRC-16. */
static inline uint16_t port_update_block(uint8_t *out, uint8_t id, uint8_t type, uint8_t num,
                                         const uint8_t *data)
{
    static uint8_t body[5u + PROTO_UPDATE_BLOCK_DATA + 2u];
    uint16_t n = type == PROTO_UPDATE_TYPE_DATA ? PROTO_UPDATE_BLOCK_DATA
                                                : PROTO_UPDATE_HEADER_DATA;
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
    return port_update_frame(out, id,
                             type == PROTO_UPDATE_TYPE_DATA ? 0xFFu : (uint8_t)(total + 1u),
                             body, total);
}

static inline uint16_t port_update_header(uint8_t *out, uint8_t id, uint32_t length)
{
    uint8_t d[PROTO_UPDATE_HEADER_DATA] = {(uint8_t)(length >> 24), (uint8_t)(length >> 16),
                                           (uint8_t)(length >> 8), (uint8_t)length};
    return port_update_block(out, id, PROTO_UPDATE_TYPE_HEADER, 0, d);
}

#endif
