#!/usr/bin/python3
"""qemu_boot.py - a servo whose application is broken stays in its bootloader and
answers the firmware update (PROTOCOL.md §10) instead: never a brick.

Boots the arm's combined image (servo-arm-full.bin, as `make flash` writes it) under QEMU
as tests/qemu_ping.py does, but with one byte of the application's code flipped (after
its info block, so the image still looks like an image and only its CRC-32 is wrong).
Then, on the bus at the arm's default 9600 baud and ID 1:
  - the update handshake D5 5D 01 03 FF FC FF is answered D5 5D 01 03 00 43 47 ('C',
    ready), after the 8 ms return delay: the bootloader's loader is listening;
  - PING ID 1 gets no answer: the broken application never started (the loader answers
    only update frames).
QEMU models no flash controller, so a whole update cannot run here; the handshake is
what shows the loader alive. tests/qemu_ping.py boots the intact image.

Usage: qemu_boot.py build/stm32/servo-arm-full.bin build/stm32/servo-arm.elf
"""
import os
import sys
import tempfile

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
import qemu_ping as q  # noqa: E402

ENTER = bytes.fromhex("D55D0103FFFCFF")
ENTER_ANSWER = bytes.fromhex("D55D0103004347")
CORRUPT_AT = 0x200      # in the application: code, past the vectors and the info block
SILENCE_S = 1.0         # PING sent this long without an answer


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


def main():
    image, elf = q.arguments("qemu_boot.py servo-arm-full.bin servo-arm.elf")
    (app_start,) = q.symbols(elf, "_app_start")
    app_offset = app_start - q.FLASH_BASE  # the application slot in the combined image
    with open(image, "rb") as f:
        data = bytearray(f.read())
    if len(data) <= app_offset + CORRUPT_AT:
        q.fail(f"{image}: {len(data)} B, no application after the bootloader")
    data[app_offset + CORRUPT_AT] ^= 0x01
    q.say(f"flipped bit 0 of the application's byte 0x{CORRUPT_AT:x} "
          f"(flash 0x{q.FLASH_BASE + app_offset + CORRUPT_AT:08x})")
    with tempfile.TemporaryDirectory() as workdir:
        broken = os.path.join(workdir, "broken-full.bin")
        with open(broken, "wb") as f:
            f.write(data)
        q.with_qemu(broken, elf, session)
    q.say("PASS")


if __name__ == "__main__":
    main()
