/* model_crc.h - the CRC-32 of the update image (IEEE 802.3, reflected, polynomial
 * 0xEDB88320, init and final xor 0xFFFFFFFF) written bit by bit from its definition,
 * with nothing of src/crc.c: the tests' reference for crc32_update() and for stamping
 * images (unit.crc, unit.image). */
#ifndef MODEL_CRC_H
#define MODEL_CRC_H

#include <stdint.h>

static inline uint32_t model_crc32(const uint8_t *p, uint32_t n)
{
    uint32_t crc = 0xFFFFFFFFu;
    for (uint32_t i = 0; i < n; i++) {
        crc ^= p[i];
        for (int b = 0; b < 8; b++)
            crc = (crc >> 1) ^ ((crc & 1u) ? 0xEDB88320u : 0u);
    }
    return ~crc;
}

#endif
