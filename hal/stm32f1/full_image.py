#!/usr/bin/env python3
"""full_image.py - the image of a whole STM32F103x8 for its first flashing: the bootloader
padded with 0xFF to its region (8 KiB: its code, then the boot record's page, so the
record starts erased), then the stamped application, which so lands at the application
slot (0x08002000; board/stm32f103x8-memory.ld). Fails if the bootloader
does not fit its region, or if the application is not a stamped image within the image
limit (include/image.h: magic "SRVI" at 0x100, length = the file's size,
IMAGE_MAX_BYTES). cmake/stm32.cmake passes the two sizes.

Usage: full_image.py BOOT_BYTES MAX_APP_BYTES servo-boot-arm.bin servo-arm.bin servo-arm-full.bin
"""
import struct
import sys

INFO_OFFSET = 0x100
MAGIC = 0x49565253  # "SRVI"


def main(boot_bytes, max_app_bytes, boot_path, app_path, out_path):
    boot_bytes, max_app_bytes = int(boot_bytes, 0), int(max_app_bytes, 0)
    boot = open(boot_path, "rb").read()
    app = open(app_path, "rb").read()
    if len(boot) > boot_bytes:
        sys.exit(f"full_image: {boot_path}: {len(boot)} B, over the bootloader's {boot_bytes}")
    if not INFO_OFFSET + 16 <= len(app) <= max_app_bytes:
        sys.exit(f"full_image: {app_path}: {len(app)} B, not an image of "
                 f"{INFO_OFFSET + 16} to {max_app_bytes} B")
    magic, length = struct.unpack_from("<II", app, INFO_OFFSET)
    if magic != MAGIC or length != len(app):
        sys.exit(f"full_image: {app_path} is not a stamped image (magic 0x{magic:08x}, "
                 f"length {length} of {len(app)} B): run tools/fwstamp.py")
    with open(out_path, "wb") as f:
        f.write(boot + b"\xff" * (boot_bytes - len(boot)) + app)
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 6:
        sys.exit(__doc__.strip().splitlines()[-1])
    sys.exit(main(*sys.argv[1:]))
