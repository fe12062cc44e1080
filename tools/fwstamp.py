#!/usr/bin/python3
"""fwstamp.py IN.bin OUT.bin - complete a firmware image's info block (include/image.h).

The STM32 build runs it after objcopy: IN is the application binary, whose info block at
offset 0x100 already holds the magic "SRVI", the model and the version; OUT is the same
binary with the info block's length (the file size) and CRC-32 filled in. Prints one
line: length, crc, model and version. Exit status 1 (one message on stderr) when IN is
not an image (no magic at 0x100, too short, too large), 2 on bad usage.

The format lives in one place, tools/python/servobus/image.py."""

import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "python"))

from servobus import image  # noqa: E402


def main(argv):
    if len(argv) != 2 or argv[0].startswith("-"):
        print("usage: fwstamp.py IN.bin OUT.bin", file=sys.stderr)
        return 2
    src, dst = argv
    try:
        with open(src, "rb") as f:
            data = f.read()
    except OSError as e:
        print("fwstamp: cannot read %s: %s" % (src, e.strerror or e), file=sys.stderr)
        return 1
    try:
        out = image.stamp(data)
        info = image.validate(out)
    except image.ImageError as e:
        print("fwstamp: %s: %s" % (src, e), file=sys.stderr)
        return 1
    tmp = dst + ".tmp"
    try:
        with open(tmp, "wb") as f:
            f.write(out)
        os.replace(tmp, dst)
    except OSError as e:
        print("fwstamp: cannot write %s: %s" % (dst, e.strerror or e), file=sys.stderr)
        return 1
    print("fwstamp: %s: %s" % (dst, info.describe()))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
