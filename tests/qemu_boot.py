#!/usr/bin/python3
"""qemu_boot.py - a servo whose application is broken, or did not confirm its last three
starts, stays in its bootloader and answers the firmware update (PROTOCOL.md §10)
instead: never a brick, never a crash loop.

Boots the arm's combined image (servo-arm-full.bin, as `make flash` writes it) under QEMU
as tests/qemu_ping.py does, four times:
  1. with one byte of the application's code flipped (after its info block, so the
     image still looks like an image and only its CRC-32 is wrong);
  2. intact, with the boot record (include/boot.h, the last KiB of the bootloader's
     region) holding three START marks and no CONFIRM: three failed starts;
  3. intact, the record holding two START marks: two failed starts, one try left;
  4. intact, the record holding three START marks, then a CONFIRM: started fine since.
In 1 and 2, on the bus at the arm's default 9600 baud and ID 1:
  - the update handshake D5 5D 01 03 FF FC FF is answered D5 5D 01 03 00 43 47 ('C',
    ready), after the 8 ms return delay: the bootloader's loader is listening;
  - PING ID 1 gets no answer: the application was not started (the loader answers
    only update frames).
In 3 and 4 the application runs: PING is answered.
QEMU models no flash controller, so a whole update cannot run here, and neither the
bootloader's START mark nor the application's CONFIRM is written (the record the image
boots with stays as loaded); the handshake is what shows the loader alive.
tests/qemu_ping.py boots the intact image with an erased record.

Usage: qemu_boot.py build/stm32/servo-arm-full.bin build/stm32/servo-arm.elf
"""
import os
import sys
import tempfile

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
import qemu_ping as q  # noqa: E402

import struct  # noqa: E402

ENTER = bytes.fromhex("D55D0103FFFCFF")
ENTER_ANSWER = bytes.fromhex("D55D0103004347")
CORRUPT_AT = 0x200      # in the application: code, past the vectors and the info block
SILENCE_S = 1.0         # PING sent this long without an answer
START, CONFIRM = 0xFF00, 0x00FF  # include/boot.h BOOT_MARK_START, BOOT_MARK_CONFIRM


def session(sock, proc):
    q.until_answered(sock, proc, ENTER, len(ENTER_ANSWER), "the update handshake")
    delay = q.ask(sock, ENTER, ENTER_ANSWER, "update handshake")
    if delay < q.RETURN_DELAY_S - 0.001:
        q.fail(f"handshake answered after {delay * 1000:.1f} ms, before the "
               f"{q.RETURN_DELAY_S * 1000:.0f} ms return delay")
    for _ in range(3):
        got, _ = q.transact(sock, q.PING, len(q.PING_ANSWER), SILENCE_S / 3)
        if got:
            q.fail(f"PING answered ({got.hex(' ')}): the broken application runs")
    q.say(f"PING: no answer within {SILENCE_S:.1f} s (the application did not start)")
    q.ask(sock, ENTER, ENTER_ANSWER, "update handshake again")


def runs(sock, proc):
    """The application was started: PING answered."""
    q.until_answered(sock, proc, q.PING, len(q.PING_ANSWER), "PING")
    q.ask(sock, q.PING, q.PING_ANSWER, "PING")


def with_record(data, record_offset, marks):
    """A copy of the combined image whose boot record holds these half-word marks."""
    data = bytearray(data)
    if data[record_offset:record_offset + 1024] != b"\xff" * 1024:
        q.fail("the combined image's boot record is not erased")
    for i, mark in enumerate(marks):
        struct.pack_into("<H", data, record_offset + 2 * i, mark)
    return data


def boot(workdir, name, data, elf, session_fn):
    path = os.path.join(workdir, name)
    with open(path, "wb") as f:
        f.write(data)
    q.with_qemu(path, elf, session_fn)


def main():
    image, elf = q.arguments("qemu_boot.py servo-arm-full.bin servo-arm.elf")
    app_start, bootrec_start = q.symbols(elf, "_app_start", "_bootrec_start")
    app_offset = app_start - q.FLASH_BASE  # the application slot in the combined image
    record_offset = bootrec_start - q.FLASH_BASE
    with open(image, "rb") as f:
        data = bytes(f.read())
    if len(data) <= app_offset + CORRUPT_AT:
        q.fail(f"{image}: {len(data)} B, no application after the bootloader")
    broken = bytearray(data)
    broken[app_offset + CORRUPT_AT] ^= 0x01
    with tempfile.TemporaryDirectory() as workdir:
        q.say(f"1. flipped bit 0 of the application's byte 0x{CORRUPT_AT:x} "
              f"(flash 0x{q.FLASH_BASE + app_offset + CORRUPT_AT:08x})")
        boot(workdir, "broken-full.bin", broken, elf, session)
        q.say(f"2. boot record (0x{bootrec_start:08x}): three starts, none confirmed")
        boot(workdir, "failed-full.bin", with_record(data, record_offset, [START] * 3), elf,
             session)
        q.say("3. boot record: two starts, none confirmed")
        boot(workdir, "two-full.bin", with_record(data, record_offset, [START] * 2), elf, runs)
        q.say("4. boot record: three starts, then a confirm")
        boot(workdir, "confirmed-full.bin",
             with_record(data, record_offset, [START] * 3 + [CONFIRM]), elf, runs)
    q.say("PASS")


if __name__ == "__main__":
    main()
