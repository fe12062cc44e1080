#!/usr/bin/python3
"""qemu_ping.py - the arm firmware, exactly as `make flash` writes it (bootloader and
stamped application, servo-arm-full.bin), answers the bus under QEMU.

Boots the combined image on QEMU's stm32vldiscovery machine (STM32F100: Cortex-M3, USART1
at the F103's address, 8 KiB RAM; RCC, flash controller, timers, GPIO and ADC are not
modelled, so the images run their clock fall-back) with USART1 on a TCP socket, and the
staging slot and the store's pages erased. The bootloader checks the application's CRC
and starts it; then, on the bus at 9600 baud:
  - PING ID 1:  D5 5D 01 02 01 04  ->  D5 5D 01 03 01 00 05, after the 8 ms return delay
  - READ of the model number (registers 0-1)  ->  the arm's 0x5203
  - 50 more of both back to back
Every frame is sent once and must be answered: a lost frame fails the test.
QEMU is always killed; the whole run is bounded well under 30 s.

Usage: qemu_ping.py build/stm32/servo-arm-full.bin build/stm32/servo-arm.elf
(the application's ELF gives the flash map's symbols; python3 standard library only).
tests/qemu_boot.py boots the same image with its application broken.
"""
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                                "tools"))
import qemu_servo  # noqa: E402  the flash map's symbols and a free port, one copy

DEADLINE_S = 25.0
BOOT_S = 10.0
FLASH_BASE = 0x08000000
PING = bytes.fromhex("D55D01020104")
PING_ANSWER = bytes.fromhex("D55D0103010005")
READ_MODEL = bytes.fromhex("D55D010402000209")   # READ addr 0, 2 bytes
READ_ANSWER = bytes.fromhex("D55D01040003525A")  # ERR 0, 0x5203 little-endian
RETURN_DELAY_S = 0.008                            # register 5 default 16 x 500 us
NAME = os.path.splitext(os.path.basename(sys.argv[0]))[0]


def fail(msg):
    print(f"{NAME}: FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def say(msg):
    print(f"{NAME}: {msg}")


def symbols(elf, *names):
    """Addresses of the flash map's symbols (tools/qemu_servo.py reads them)."""
    try:
        return qemu_servo.symbols(elf, *names)
    except (OSError, subprocess.CalledProcessError, RuntimeError) as e:
        fail(f"arm-none-eabi-nm {elf}: {e}")


free_port = qemu_servo.free_port


def transact(sock, frame, want, timeout_s=0.4):
    """Send frame; return (answer bytes, seconds to the first answer byte)."""
    sock.sendall(frame)
    try:
        return qemu_servo.receive(sock, want, timeout_s)
    except ConnectionError as e:
        fail(str(e))


def ask(sock, frame, answer, what):
    """One request, sent once: a lost frame is a lost command on a real bus, so no
    answer fails the test; exact answer required."""
    got, first = transact(sock, frame, len(answer))
    if got != answer:
        fail(f"{what}: sent {frame.hex(' ')}, expected {answer.hex(' ')}, got "
             f"{got.hex(' ') or 'nothing'}")
    say(f"{what}: {frame.hex(' ')} -> {got.hex(' ')} after {first * 1000:.1f} ms")
    return first


def until_answered(sock, proc, frame, want, what):
    """Resend frame until something answers (the image is booting); the answer."""
    t0 = time.monotonic()
    while True:
        got, _ = transact(sock, frame, want, 0.3)
        if got:
            say(f"booted, first answer to {what} after {time.monotonic() - t0:.2f} s")
            return got
        if proc.poll() is not None:
            fail(f"QEMU exited ({proc.returncode}) during boot: the image reset or faulted")
        if time.monotonic() - t0 > BOOT_S:
            fail(f"no answer to {what} within {BOOT_S:.0f} s of boot")


def with_qemu(image, elf, session):
    """Boot image (a whole-flash image from FLASH_BASE) with the staging slot and the
    store erased, USART1 on a socket; session(sock, proc) talks to it. QEMU is always
    killed."""
    qemu = "qemu-system-arm"
    try:
        subprocess.run([qemu, "--version"], check=True, capture_output=True)
    except (OSError, subprocess.CalledProcessError):
        fail("qemu-system-arm not found: tools/install-deps.sh installs it")
    staging, store_end = symbols(elf, "_staging_start", "_store_end")
    with tempfile.TemporaryDirectory() as workdir:
        erased = os.path.join(workdir, "erased.bin")
        with open(erased, "wb") as f:  # QEMU's flash starts as zeros, silicon's as 0xFF
            f.write(b"\xff" * (store_end - staging))
        for _ in range(3):  # a port taken between choosing and binding: choose again
            port = free_port()
            cmd = [qemu, "-M", "stm32vldiscovery", "-nographic", "-monitor", "none",
                   "-no-reboot",
                   "-device", f"loader,file={image},addr=0x{FLASH_BASE:08x}",
                   "-device", f"loader,file={erased},addr=0x{staging:08x}",
                   "-serial", f"tcp:127.0.0.1:{port},server=on,wait=off,nodelay=on"]
            proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
            try:
                sock = None
                t0 = time.monotonic()
                while sock is None and proc.poll() is None and time.monotonic() - t0 < 5:
                    try:
                        sock = socket.create_connection(("127.0.0.1", port), timeout=1)
                    except OSError:
                        time.sleep(0.05)
                if sock is None:
                    continue
                with sock:
                    say(" ".join(cmd))
                    session(sock, proc)
                    if proc.poll() is not None:
                        fail(f"QEMU exited ({proc.returncode})")
                    return
            finally:
                proc.kill()
                out = proc.communicate(timeout=5)[0].decode(errors="replace").strip()
                if out and "terminating" not in out:
                    say("QEMU said: " + out)
    fail("could not start QEMU with a serial socket")


def arguments(usage):
    """(combined image, application ELF) from the command line; the deadline armed."""
    if len(sys.argv) != 3:
        fail("usage: " + usage)
    for path in sys.argv[1:]:
        if not os.path.isfile(path):
            fail(f"{path} not found: build the stm32 preset first (make stm32)")
    signal.signal(signal.SIGALRM, lambda *_: fail(f"over {DEADLINE_S:.0f} s"))
    signal.setitimer(signal.ITIMER_REAL, DEADLINE_S)
    return sys.argv[1], sys.argv[2]


def ping_session(sock, proc):
    until_answered(sock, proc, PING, len(PING_ANSWER), "PING")
    delay = ask(sock, PING, PING_ANSWER, "PING")
    if delay < RETURN_DELAY_S - 0.001:
        fail(f"PING answered after {delay * 1000:.1f} ms, before the "
             f"{RETURN_DELAY_S * 1000:.0f} ms return delay")
    ask(sock, READ_MODEL, READ_ANSWER, "READ model number")
    ask(sock, PING, PING_ANSWER, "PING again")
    for i in range(50):  # every frame answered, back to back
        ask(sock, READ_MODEL if i % 2 else PING, READ_ANSWER if i % 2 else PING_ANSWER,
            f"frame {i + 1} of 50 back to back")


def main():
    image, elf = arguments("qemu_ping.py servo-arm-full.bin servo-arm.elf")
    with_qemu(image, elf, ping_session)
    say("PASS")


if __name__ == "__main__":
    main()
