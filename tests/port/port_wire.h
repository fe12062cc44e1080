/* port_wire.h - what the port tests put on the bus and in flash: application images
 * (image.h layout, stamped with the core's CRC-32) and the host's frames, the §10
 * update frames included (PROTOCOL.md §10, tests/update_wire.h). */
#ifndef PORT_WIRE_H
#define PORT_WIRE_H

#include <stdint.h>
#include <string.h>

#include "image.h"
#include "host/image_build.h"
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
    hal_host_image_build(img, len, model_number, version, seed);
    port_put32(&img[0], 0x20001800u);
    port_put32(&img[4], 0x08002000u + 0x400u + (seed % 256u) * 4u + 1u);
    hal_host_image_stamp(img, len);
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
