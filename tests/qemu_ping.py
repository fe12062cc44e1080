#!/usr/bin/python3
"""qemu_ping.py - the arm firmware image, exactly as `make flash` writes it, answers the
bus under QEMU.

Boots the STM32 image on QEMU's stm32vldiscovery machine (STM32F100: Cortex-M3, USART1
at the F103's address, 8 KiB RAM; RCC, flash controller, timers, GPIO and ADC are not
modelled, so the image runs its clock fall-back), with USART1 on a TCP socket and the
store's flash pages erased, then on the bus at 9600 baud:
  - PING ID 1:  D5 5D 01 02 01 04  ->  D5 5D 01 03 01 00 05, after the 8 ms return delay
  - READ of the model number (registers 0-1)  ->  the arm's 0x5203
QEMU is always killed; the whole run is bounded well under 30 s.

Usage: qemu_ping.py build/stm32/servo-arm.elf   (python3 standard library only)
"""
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time

DEADLINE_S = 25.0
BOOT_S = 10.0
PING = bytes.fromhex("D55D01020104")
PING_ANSWER = bytes.fromhex("D55D0103010005")
READ_MODEL = bytes.fromhex("D55D010402000209")   # READ addr 0, 2 bytes
READ_ANSWER = bytes.fromhex("D55D01040003525A")  # ERR 0, 0x5203 little-endian
RETURN_DELAY_S = 0.008                            # register 5 default 16 x 500 us
ATTEMPTS = 3


def fail(msg):
    print(f"qemu_ping: FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def store_start(elf):
    """Address of the store's pages, from the image's own symbol table."""
    try:
        out = subprocess.run(["arm-none-eabi-nm", elf], check=True, capture_output=True,
                             text=True).stdout
    except (OSError, subprocess.CalledProcessError) as e:
        fail(f"arm-none-eabi-nm {elf}: {e}")
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[2] == "_store_start":
            return int(parts[0], 16)
    fail(f"{elf} has no _store_start symbol")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def transact(sock, frame, want, timeout_s=0.4):
    """Send frame; return (answer bytes, seconds to the first answer byte)."""
    sock.sendall(frame)
    start = time.monotonic()
    got, first = b"", None
    sock.settimeout(0.05)
    while len(got) < want and time.monotonic() - start < timeout_s:
        try:
            chunk = sock.recv(64)
        except socket.timeout:
            continue
        if not chunk:
            fail("QEMU closed the serial socket")
        if first is None:
            first = time.monotonic() - start
        got += chunk
    return got, first


def ask(sock, frame, answer, what):
    """One request, resent if unanswered (a lost frame); exact answer required."""
    for attempt in range(1, ATTEMPTS + 1):
        got, first = transact(sock, frame, len(answer))
        if got:
            break
        print(f"qemu_ping: warning: no answer to {what} (attempt {attempt})")
        time.sleep(0.05)
    if got != answer:
        fail(f"{what}: sent {frame.hex(' ')}, expected {answer.hex(' ')}, got "
             f"{got.hex(' ') or 'nothing'}")
    print(f"qemu_ping: {what}: {frame.hex(' ')} -> {got.hex(' ')} after "
          f"{first * 1000:.1f} ms")
    return first


def run(elf, qemu, workdir):
    erased = os.path.join(workdir, "store.bin")
    with open(erased, "wb") as f:
        f.write(b"\xff" * 4096)
    base = store_start(elf)
    for _ in range(3):  # a port taken between choosing and binding: choose again
        port = free_port()
        cmd = [qemu, "-M", "stm32vldiscovery", "-nographic", "-monitor", "none",
               "-no-reboot", "-kernel", elf,
               "-device", f"loader,file={erased},addr=0x{base:08x}",
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
                print("qemu_ping: " + " ".join(cmd))
                # Boot: the image answers once servo_init is done.
                t0 = time.monotonic()
                while True:
                    got, _ = transact(sock, PING, len(PING_ANSWER), 0.3)
                    if got:
                        break
                    if proc.poll() is not None:
                        fail(f"QEMU exited ({proc.returncode}) during boot: the image "
                             "reset or faulted")
                    if time.monotonic() - t0 > BOOT_S:
                        fail(f"no answer to PING within {BOOT_S:.0f} s of boot")
                print(f"qemu_ping: booted, first answer after "
                      f"{time.monotonic() - t0:.2f} s")
                delay = ask(sock, PING, PING_ANSWER, "PING")
                if delay < RETURN_DELAY_S - 0.001:
                    fail(f"PING answered after {delay * 1000:.1f} ms, before the "
                         f"{RETURN_DELAY_S * 1000:.0f} ms return delay")
                ask(sock, READ_MODEL, READ_ANSWER, "READ model number")
                ask(sock, PING, PING_ANSWER, "PING again")
                if proc.poll() is not None:
                    fail(f"QEMU exited ({proc.returncode})")
                return
        finally:
            proc.kill()
            out = proc.communicate(timeout=5)[0].decode(errors="replace").strip()
            if out and "terminating" not in out:
                print("qemu_ping: QEMU said: " + out)
    fail("could not start QEMU with a serial socket")


def main():
    if len(sys.argv) != 2:
        fail("usage: qemu_ping.py servo-arm.elf")
    elf = sys.argv[1]
    if not os.path.isfile(elf):
        fail(f"{elf} not found: build the stm32 preset first (make stm32)")
    qemu = "qemu-system-arm"
    try:
        subprocess.run([qemu, "--version"], check=True, capture_output=True)
    except (OSError, subprocess.CalledProcessError):
        fail("qemu-system-arm not found: tools/install-deps.sh installs it")
    signal.signal(signal.SIGALRM, lambda *_: fail(f"over {DEADLINE_S:.0f} s"))
    signal.setitimer(signal.ITIMER_REAL, DEADLINE_S)
    with tempfile.TemporaryDirectory() as workdir:
        run(elf, qemu, workdir)
    print("qemu_ping: PASS")


if __name__ == "__main__":
    main()
