/* port_wire.h - what the port tests put on the bus and in flash: application images
 * (image.h layout, stamped with the core's CRC-32) and the host's frames, the §10
 * update frames included (PROTOCOL.md §10, tests/update_wire.h). */
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

/* §10 frames: the one builder the host tests share (enter_frame(), header_frame(),
 * block_frame(), eof_frame(), ...). */
#include "../update_wire.h"

#endif
