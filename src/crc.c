/* crc.c - CRC-32 and CRC-16 (crc.h). CRC-32 goes four bits at a time through a 64-byte
 * table: the bootloader checks a whole image at every reset, before it has set up the
 * PLL (8 MHz), and bit by bit that would cost ~90 ms for 16 KiB. */
#include "crc.h"

/* CRC-32 of each 4-bit value, reflected polynomial 0xEDB88320. */
static const uint32_t crc32_nibble[16] = {
    0x00000000u, 0x1DB71064u, 0x3B6E20C8u, 0x26D930ACu, 0x76DC4190u, 0x6B6B51F4u,
    0x4DB26158u, 0x5005713Cu, 0xEDB88320u, 0xF00F9344u, 0xD6D6A3E8u, 0xCB61B38Cu,
    0x9B64C2B0u, 0x86D3D2D4u, 0xA00AE278u, 0xBDBDF21Cu,
};

uint32_t crc32_update(uint32_t crc, const uint8_t *p, uint32_t n)
{
    while (n--) {
        crc ^= *p++;
        crc = (crc >> 4) ^ crc32_nibble[crc & 0x0Fu];
        crc = (crc >> 4) ^ crc32_nibble[crc & 0x0Fu];
    }
    return crc;
}

uint16_t crc16_update(uint16_t crc, const uint8_t *p, uint32_t n)
{
    while (n--) {
        crc ^= (uint16_t)((uint16_t)*p++ << 8);
        for (uint8_t k = 0; k < 8u; k++)
            crc = (uint16_t)(((uint32_t)crc << 1) ^ ((crc & 0x8000u) ? 0x1021u : 0u));
    }
    return crc;
}
