/* crc.h - the two checks the firmware computes over flash and frames. CRC-32 four bits
 * at a time through a 64-byte table (the bootloader checks a whole image at every reset,
 * on the 8 MHz clock: crc.c), CRC-16 bit by bit (short inputs; the bootloader shares this
 * code and has its 5.5 KiB goal). Pure functions. */
#ifndef CRC_H
#define CRC_H

#include <stdint.h>

/* CRC-32 (IEEE 802.3, reflected, polynomial 0xEDB88320): start with CRC32_INIT, feed
 * the bytes, finish with ~crc. Standard CRC-32 of "123456789" is 0xCBF43926. */
#define CRC32_INIT 0xFFFFFFFFu
uint32_t crc32_update(uint32_t crc, const uint8_t *p, uint32_t n);

/* CRC-16 with polynomial 0x1021, most significant bit first, no final xor: from 0 it is
 * CRC-16/XMODEM (PROTOCOL.md §10; "123456789" gives 0x31C3), from 0xFFFF
 * CRC-16/CCITT-FALSE (the store's records). */
uint16_t crc16_update(uint16_t crc, const uint8_t *p, uint32_t n);

#endif
