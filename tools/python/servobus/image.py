"""Firmware images (include/image.h): parse, check, stamp and synthesise them.

An image is the application binary linked for the application slot. At INFO_OFFSET
(0x100) it carries a 16-byte info block, all fields little-endian:

    +0  magic    b"SRVI" (0x49565253)
    +4  length   bytes of the image, info block included
    +8  crc      CRC-32 (zlib.crc32) of image bytes [0, length) with these 4 bytes as 0
    +12 model    model number of the board it is built for (registers 0-1)
    +14 version  firmware version (register 2)
    +15 reserved 0

The build (tools/fwstamp.py) fills length and crc; the firmware declares the rest. A
servo takes an image whose magic, length (MIN_BYTES..MAX_BYTES), model and CRC match.
Pure functions, no I/O."""

import random
import struct
import zlib

from .errors import ServoBusError

INFO_OFFSET = 0x100
INFO_BYTES = 16
MAGIC = b"SRVI"
MIN_BYTES = INFO_OFFSET + INFO_BYTES   # 0x110
# The flash slots (hal/hal.h): 26 pages of 1 KiB; the staging slot's last 4 bytes hold
# the install mark, so an image has 4 bytes less (IMAGE_MAX_BYTES in include/image.h;
# tests/test_update.py checks these against the headers).
PAGE_BYTES = 1024
SLOT_PAGES = 26
MAX_BYTES = SLOT_PAGES * PAGE_BYTES - 4
OFF_LENGTH = INFO_OFFSET + 4
OFF_CRC = INFO_OFFSET + 8
_INFO = struct.Struct("<4sIIHBB")

# Model numbers of the boards (registers 0-1).
MODELS = {"base": 0x5201, "foot": 0x5202, "arm": 0x5203, "wrist": 0x5204,
          "finger": 0x5205}


class ImageError(ServoBusError, ValueError):
    """A file that is not a valid firmware image; the message says what is wrong."""


class ImageInfo:
    """The info block of an image: length, crc, model, version, reserved; size (bytes of
    the file) and crc_ok (the stored CRC matches the content)."""

    __slots__ = ("length", "crc", "model", "version", "reserved", "size", "crc_ok")

    def __init__(self, length, crc, model, version, reserved, size, crc_ok):
        self.length = length
        self.crc = crc
        self.model = model
        self.version = version
        self.reserved = reserved
        self.size = size
        self.crc_ok = crc_ok

    @property
    def variant(self):
        """The board name of the model number, or None."""
        for name, model in MODELS.items():
            if model == self.model:
                return name
        return None

    def describe(self):
        """One line: length, CRC, model (and board) and version."""
        return "length %d bytes, crc 0x%08X, model 0x%04X (%s), version %d" % (
            self.length, self.crc, self.model, self.variant or "unknown board", self.version)

    def __repr__(self):
        return "ImageInfo(%s)" % self.describe()


def image_crc(data):
    """CRC-32 of data with the crc field (bytes 0x108-0x10B) read as 0."""
    data = bytes(data)
    return zlib.crc32(data[:OFF_CRC] + b"\0\0\0\0" + data[OFF_CRC + 4:]) & 0xFFFFFFFF


def _info_fields(data):
    """(magic, length, crc, model, version, reserved) read from the info block."""
    return _INFO.unpack_from(bytes(data), INFO_OFFSET)


def parse(data):
    """The ImageInfo of data, without judging it (crc_ok says whether the CRC matches).
    ImageError if data is too short to hold the info block or has no magic there."""
    data = bytes(data)
    if len(data) < MIN_BYTES:
        raise ImageError("not a firmware image: %d bytes, too short to hold the info "
                         "block (an image has at least %d bytes)" % (len(data), MIN_BYTES))
    magic, length, crc, model, version, reserved = _info_fields(data)
    if magic != MAGIC:
        raise ImageError("not a firmware image: no magic \"SRVI\" at offset 0x%X (found "
                         "%s) — a raw binary without the info block, or the wrong file?" %
                         (INFO_OFFSET, magic.hex(" ")))
    crc_ok = length == len(data) and image_crc(data) == crc
    return ImageInfo(length, crc, model, version, reserved, len(data), crc_ok)


def validate(data, model=None):
    """Check data as a servo would (magic, length, size, CRC and, if given, the model):
    the ImageInfo, or ImageError saying what is wrong."""
    info = parse(data)
    if info.size > MAX_BYTES:
        raise ImageError("image too large: %d bytes, an image has %d at most" %
                         (info.size, MAX_BYTES))
    if info.length != info.size:
        if info.length > info.size:
            raise ImageError("truncated image: the info block says %d bytes, the file has "
                             "%d" % (info.length, info.size))
        raise ImageError("length mismatch: the info block says %d bytes, the file has %d "
                         "(not stamped? run tools/fwstamp.py)" % (info.length, info.size))
    if not info.crc_ok:
        raise ImageError("bad CRC: the info block says 0x%08X, the content gives 0x%08X "
                         "(corrupted, or not stamped? run tools/fwstamp.py)" %
                         (info.crc, image_crc(data)))
    if model is not None and info.model != model:
        names = {v: k for k, v in MODELS.items()}
        raise ImageError("image built for model 0x%04X (%s), the servo is model 0x%04X (%s)"
                         % (info.model, names.get(info.model, "unknown board"), model,
                            names.get(model, "unknown board")))
    return info


def stamp(data):
    """data with the length (= len(data)) and CRC fields of its info block filled in.
    The magic, model and version must already be there (the firmware declares them)."""
    data = bytearray(data)
    parse(data)  # magic and minimum size
    if len(data) > MAX_BYTES:
        raise ImageError("image too large: %d bytes, an image has %d at most" %
                         (len(data), MAX_BYTES))
    struct.pack_into("<I", data, OFF_LENGTH, len(data))
    struct.pack_into("<I", data, OFF_CRC, image_crc(data))
    return bytes(data)


def info_block(model, version, length=0, crc=0):
    """The 16 bytes of an info block."""
    return _INFO.pack(MAGIC, length, crc, model, version, 0)


def build(length, version, model, seed=0):
    """A synthetic valid image of length bytes (pseudo-random content from seed, the info
    block at 0x100, stamped), for tests and benchmarks."""
    if not MIN_BYTES <= length <= MAX_BYTES:
        raise ImageError("an image has %d..%d bytes, not %d" % (MIN_BYTES, MAX_BYTES, length))
    if not 0 <= version <= 0xFF or not 0 <= model <= 0xFFFF:
        raise ImageError("version is 0..255 and model 0..65535")
    rng = random.Random(seed)
    data = bytearray(rng.getrandbits(8 * length).to_bytes(length, "little"))
    data[INFO_OFFSET:INFO_OFFSET + INFO_BYTES] = info_block(model, version)
    return stamp(data)
