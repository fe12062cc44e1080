/* image_info.c - the application image's info block (image.h): in its own section, which
 * the linker script (board/stm32f103x8.ld) places at exactly IMAGE_INFO_OFFSET from the
 * slot's start. The build declares magic, model and version here; tools/fwstamp.py fills
 * length and CRC-32 into the .bin after the link (the ELF keeps them 0). */
#include <stddef.h>
#include <stdint.h>

#include "board.h"
#include "image.h"

#ifndef SERVO_MODEL
#error "SERVO_MODEL (BOARD_MODEL_ARM, ...) comes from CMake's BOARD"
#endif

struct info_block {
    uint32_t magic, length, crc;
    uint16_t model;
    uint8_t version, reserved;
};
_Static_assert(sizeof(struct info_block) == IMAGE_INFO_BYTES, "image.h: 16 bytes");
_Static_assert(offsetof(struct info_block, magic) == IMAGE_OFF_MAGIC &&
                   offsetof(struct info_block, length) == IMAGE_OFF_LENGTH &&
                   offsetof(struct info_block, crc) == IMAGE_OFF_CRC &&
                   offsetof(struct info_block, model) == IMAGE_OFF_MODEL &&
                   offsetof(struct info_block, version) == IMAGE_OFF_VERSION,
               "image.h layout");
_Static_assert(SERVO_FW_VERSION >= 0 && SERVO_FW_VERSION <= 255, "register 2 is a byte");
/* full_image.py takes the slot's size from cmake/stm32.cmake, which defines it for this
 * file: it must be the one the bootloader and the update session check (image.h). */
#ifdef SERVO_APP_MAX_BYTES
_Static_assert(SERVO_APP_MAX_BYTES == IMAGE_MAX_BYTES, "cmake/stm32.cmake: IMAGE_MAX_BYTES");
#endif

/* Little-endian on the Cortex-M3, as image.h wants. */
__attribute__((section(".image_info"), used)) static const struct info_block image_info = {
    .magic = IMAGE_MAGIC,
    .length = 0, /* tools/fwstamp.py */
    .crc = 0,    /* tools/fwstamp.py */
    .model = SERVO_MODEL,
    .version = SERVO_FW_VERSION,
    .reserved = 0,
};
