/* image.h - what makes a flash slot a bootable application image, and the check the
 * bootloader and the update session apply to it.
 *
 * An image is the application binary linked for the application slot (vector table at
 * offset 0). At IMAGE_INFO_OFFSET it carries an info block the firmware declares and a
 * build step (tools/fwstamp.py) completes; all fields little-endian:
 *   +0  magic    "SRVI" (IMAGE_MAGIC)
 *   +4  length   bytes of the image, info block included
 *   +8  crc      CRC-32 (crc.h) of image bytes [0, length) with these 4 bytes read as 0
 *   +12 model    model number of the board the image is built for (registers 0-1)
 *   +14 version  firmware version (register 2)
 *   +15 reserved 0
 * An image is valid for a servo when the magic, the length (IMAGE_MIN_BYTES ..
 * IMAGE_MAX_BYTES), the model and the CRC all match. Main loop / bootloader only. */
#ifndef IMAGE_H
#define IMAGE_H

#include <stdbool.h>
#include <stdint.h>

#include "hal.h"

#define IMAGE_INFO_OFFSET 0x100u /* after the STM32F103's 236-byte vector table */
#define IMAGE_INFO_BYTES 16u
#define IMAGE_MAGIC 0x49565253u  /* "SRVI" */
#define IMAGE_OFF_MAGIC 0u
#define IMAGE_OFF_LENGTH 4u
#define IMAGE_OFF_CRC 8u
#define IMAGE_OFF_MODEL 12u
#define IMAGE_OFF_VERSION 14u
#define IMAGE_OFF_RESERVED 15u
#define IMAGE_MIN_BYTES (IMAGE_INFO_OFFSET + IMAGE_INFO_BYTES)
#define IMAGE_MAX_BYTES (HAL_SLOT_PAGES * HAL_FLASH_PAGE_BYTES - 4u)

/* The install mark: the half-word IMAGE_MARK_OFFSET of the staging slot's last page,
 * past any image. The update session erases it when a header is accepted and programs it
 * to 0 once the whole image has been verified (the end-of-batch ACK); the bootloader
 * installs a staged image only while it is 0. So only an image the servo acknowledged
 * is ever installed, even if a cut or an abandoned session left a complete copy. */
#define IMAGE_MARK_PAGE (HAL_PAGE_STAGING + HAL_SLOT_PAGES - 1u)
#define IMAGE_MARK_OFFSET (HAL_FLASH_PAGE_BYTES - 4u)
#define IMAGE_MARK_SET 0x0000u

/* Make flash page `page` hold the n bytes at data (n even, at most HAL_FLASH_PAGE_BYTES)
 * and erased bytes after them: erase, program every half-word that is not 0xFFFF, read
 * back. False on any failure. (An update block into the staging slot: only the image's
 * own bytes, never the block's padding, so no data block can write the install mark; a
 * staging page into the application slot at install.) */
bool image_write_page(struct hal *hal, uint8_t page, const uint8_t *data, uint16_t n);

/* Is the install mark set? */
bool image_marked(struct hal *hal);

struct image_info {
    uint32_t length;
    uint32_t crc;
    uint16_t model;
    uint8_t version;
};

/* Decode the info block from the first page of an image (page0 holds at least
 * IMAGE_MIN_BYTES). False when the magic or the length is wrong. */
bool image_parse_info(const uint8_t *page0, struct image_info *out);

/* CRC-32 of the image of length bytes whose first page is first_page, the crc field
 * read as 0 (finished, i.e. comparable with the info block's crc). */
uint32_t image_crc(struct hal *hal, uint8_t first_page, uint32_t length);

/* Is the slot starting at first_page a valid image for a board of this model? Fills
 * *out (may be 0) when it is. */
bool image_valid(struct hal *hal, uint8_t first_page, uint16_t model, struct image_info *out);

#endif
