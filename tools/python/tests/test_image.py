"""The firmware image (docs/update.md): servobus.image (parse, validate, stamp, build)
against the firmware's headers and the register table, and tools/fwstamp.py."""

import os
import shutil
import struct
import subprocess
import sys
import zlib

import pytest

from conftest import REPO
from servobus import ImageError, VARIANTS
from servobus import image as I

ARM = VARIANTS["arm"].model_number
FOOT = VARIANTS["foot"].model_number
FWSTAMP = os.path.join(REPO, "tools", "fwstamp.py")
APP_SLOT = 4 * 1024  # byte offset of the application slot in a --state-dir flash file

# ---- the image module and fwstamp.py ------------------------------------------------

def c_defines(*paths):
    """The integer #defines of C headers, evaluated in order (simple expressions)."""
    import re
    values = {}
    for path in paths:
        with open(os.path.join(REPO, path)) as f:
            for name, expr in re.findall(r"^#define (\w+) ([^/\n]+)", f.read(), re.M):
                expr = re.sub(r"(\d+|0x[0-9A-Fa-f]+)u\b", r"\1", expr.strip())
                try:
                    values[name] = eval(expr, {}, dict(values))  # noqa: S307 (own headers)
                except Exception:
                    pass
    return values


def test_image_format_matches_the_firmware_headers():
    c = c_defines("hal/hal.h", "include/image.h")
    assert I.INFO_OFFSET == c["IMAGE_INFO_OFFSET"] and I.INFO_BYTES == c["IMAGE_INFO_BYTES"]
    assert I.MIN_BYTES == c["IMAGE_MIN_BYTES"] and I.MAX_BYTES == c["IMAGE_MAX_BYTES"]
    assert (I.PAGE_BYTES, I.SLOT_PAGES) == (c["HAL_FLASH_PAGE_BYTES"], c["HAL_SLOT_PAGES"])
    assert I.MAGIC == c["IMAGE_MAGIC"].to_bytes(4, "little")
    assert (I.OFF_LENGTH, I.OFF_CRC) == (I.INFO_OFFSET + c["IMAGE_OFF_LENGTH"],
                                         I.INFO_OFFSET + c["IMAGE_OFF_CRC"])
    assert APP_SLOT == c["HAL_PAGE_APP"] * c["HAL_FLASH_PAGE_BYTES"]


def test_model_numbers_are_every_board_of_the_one_list():
    # Issue 28: from registers.json's boards (make docs), not a hand copy, so a sixth board
    # added to cmake/boards.cmake is an image this SDK can name and check.
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
    import boards  # tools/boards.py: the one board list
    assert list(I.MODELS) == boards.names()
    assert {v.name: v.model_number for v in VARIANTS.values()}.items() <= I.MODELS.items()


def test_build_makes_a_valid_image():
    data = I.build(16384, version=7, model=ARM, seed=3)
    assert len(data) == 16384 and data[0x100:0x104] == b"SRVI"
    info = I.validate(data, ARM)
    assert (info.length, info.model, info.version, info.crc_ok) == (16384, ARM, 7, True)
    magic, length, crc, model, version, reserved = struct.unpack_from("<4sIIHBB", data, 0x100)
    blank = data[:0x108] + b"\0\0\0\0" + data[0x10C:]
    assert crc == zlib.crc32(blank) and (length, model, version, reserved) == (16384, ARM, 7, 0)
    assert I.build(16384, 7, ARM, seed=3) == data != I.build(16384, 7, ARM, seed=4)
    assert len(I.build(I.MIN_BYTES, 1, ARM)) == 0x110
    assert len(I.build(I.MAX_BYTES, 1, ARM)) == I.MAX_BYTES
    for bad in (I.MIN_BYTES - 1, I.MAX_BYTES + 1):
        with pytest.raises(ImageError):
            I.build(bad, 1, ARM)


def corrupt(data, offset=5000):
    data = bytearray(data)
    data[offset] ^= 0x01
    return bytes(data)


@pytest.mark.parametrize("mangle,words", [
    (lambda d: corrupt(d), ["bad CRC"]),
    (lambda d: corrupt(d, 0x10A), ["bad CRC"]),  # the stored CRC itself
    (lambda d: d[:-100], ["truncated", "16384", "16284"]),
    (lambda d: d + b"\xFF" * 16, ["length mismatch", "fwstamp"]),
    (lambda d: d[:0x100] + b"XRVI" + d[0x104:], ["no magic", "0x100"]),
    (lambda d: d[:0x80], ["too short"]),
    (lambda d: I.stamp(d + bytes(I.MAX_BYTES - len(d))) + b"\0",
     ["too large", str(I.MAX_BYTES)]),
])
def test_validate_says_what_is_wrong(mangle, words):
    data = mangle(I.build(16384, 7, ARM))
    with pytest.raises(ImageError) as e:
        I.validate(data)
    assert isinstance(e.value, ValueError)
    for w in words:
        assert w in str(e.value), (w, str(e.value))


def test_validate_checks_the_model():
    with pytest.raises(ImageError, match=r"model 0x5203 \(arm\).*model 0x5202 \(foot\)"):
        I.validate(I.build(4096, 7, ARM), FOOT)


def test_stamp_fills_length_and_crc_only():
    raw = bytearray(5000)
    raw[0x100:0x110] = I.info_block(FOOT, 9)
    out = I.stamp(raw)
    info = I.validate(out, FOOT)
    assert (info.length, info.version) == (5000, 9)
    assert out[:0x104] == raw[:0x104] and out[0x10C:] == raw[0x10C:]
    assert I.stamp(out) == out  # idempotent
    with pytest.raises(ImageError, match="no magic"):
        I.stamp(bytes(5000))


@pytest.mark.parametrize("python", sorted(
    {sys.executable, "/usr/bin/python3", shutil.which("python3") or "python3"}))
def test_fwstamp(tmp_path, python):
    if not shutil.which(python):
        pytest.skip("no %s" % python)
    raw = bytearray(os.urandom(3000))
    raw[0x100:0x110] = I.info_block(ARM, 4)
    src, dst = tmp_path / "app.bin", tmp_path / "app.img"
    src.write_bytes(raw)
    p = subprocess.run([python, FWSTAMP, str(src), str(dst)], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    info = I.validate(dst.read_bytes(), ARM)
    assert p.stdout.count("\n") == 1
    for w in ("length 3000", "crc 0x%08X" % info.crc, "model 0x5203", "version 4"):
        assert w in p.stdout
    src.write_bytes(os.urandom(3000))
    p = subprocess.run([python, FWSTAMP, str(src), str(tmp_path / "x.img")],
                       capture_output=True, text=True)
    assert p.returncode == 1 and "no magic" in p.stderr and not (tmp_path / "x.img").exists()
    p = subprocess.run([python, FWSTAMP, str(src)], capture_output=True, text=True)
    assert p.returncode == 2 and "usage" in p.stderr


def test_fwstamp_is_executable():
    assert os.access(FWSTAMP, os.X_OK)
    with open(FWSTAMP) as f:
        assert f.readline().strip() == "#!/usr/bin/python3"
