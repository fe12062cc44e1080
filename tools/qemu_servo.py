#!/usr/bin/python3
"""qemu_servo.py - the arm firmware of the `qemu` build (build/qemu/servo-qemu-full.bin:
the bootloader and the stamped application, as flashed) on qemu-system-arm -M
stm32vldiscovery, USART1 on a TCP port. `make qemu` runs it until Ctrl-C; the QEMU tests
(tests/qemu_servo_test.py) and `make demo QEMU=1` start it through start().

QEMU's flash starts as zeros, silicon's as 0xFF: the staging slot and the store's pages
are loaded erased. -no-reboot: a reset (a fault; nothing else restarts the MCU under
QEMU) ends QEMU instead of booting again, so it cannot pass unnoticed.

QEMU's STM32F100 has no unique-ID region: an instance's UID (issue 27, hal_uid()) is 12
bytes loaded at 0x0801FFF0, the top of its 128 KiB flash (QemuServo(uid=...), --uid);
without one it reads 12 zero bytes.

Usage: qemu_servo.py [--port N] [build/qemu/servo-qemu-full.bin build/qemu/servo-qemu.elf]
"""
import argparse
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
IMAGE = os.path.join(REPO, "build", "qemu", "servo-qemu-full.bin")
ELF = os.path.join(REPO, "build", "qemu", "servo-qemu.elf")
FLASH_BASE = 0x08000000
UID_ADDR = 0x0801FFF0  # hal/stm32f1/qemu_flash.c hal_uid(): QEMU models no unique-ID region
PING = bytes.fromhex("D55D01020104")


def symbols(elf, *names):
    """Addresses of the flash map's symbols, from the application's symbol table."""
    out = subprocess.run(["arm-none-eabi-nm", elf], check=True, capture_output=True,
                         text=True).stdout
    found = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[2] in names:
            found[parts[2]] = int(parts[0], 16)
    missing = [n for n in names if n not in found]
    if missing:
        raise RuntimeError(f"{elf} has no {' '.join(missing)} (linker script?)")
    return [found[n] for n in names]


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def receive(sock, want, timeout):
    """Up to `want` bytes from QEMU's serial socket within timeout seconds; returns
    (bytes, seconds to the first, or None). ConnectionError if QEMU closed it."""
    start = time.monotonic()
    got, first = b"", None
    while len(got) < want and time.monotonic() - start < timeout:
        sock.settimeout(max(0.001, timeout - (time.monotonic() - start)))
        try:
            chunk = sock.recv(256)
        except socket.timeout:
            break
        if not chunk:
            raise ConnectionError("QEMU closed the serial socket")
        if first is None:
            first = time.monotonic() - start
        got += chunk
    return got, first


class QemuServo:
    """One emulated MCU: proc (the QEMU process), port (USART1's TCP port, a server that
    takes one client at a time), url (tcp://127.0.0.1:port). stop() always kills it."""

    def __init__(self, image=IMAGE, elf=ELF, port=None, extra=(), uid=None):
        for path in (image, elf):
            if not os.path.isfile(path):
                raise FileNotFoundError(f"{path} not found: build the qemu preset first "
                                        "(make qemu, or cmake --preset qemu && cmake "
                                        "--build --preset qemu)")
        staging, store_end = symbols(elf, "_staging_start", "_store_end")
        self.tmp = tempfile.TemporaryDirectory()
        erased = os.path.join(self.tmp.name, "erased.bin")
        with open(erased, "wb") as f:
            f.write(b"\xff" * (store_end - staging))
        if uid is not None:  # hal_uid() under QEMU: 12 bytes at the top of flash
            if len(uid) != 12:
                raise ValueError("a UID is 12 bytes")
            path = os.path.join(self.tmp.name, "uid.bin")
            with open(path, "wb") as f:
                f.write(bytes(uid))
            extra = ("-device", f"loader,file={path},addr=0x{UID_ADDR:08x}", *extra)
        self.port = port or free_port()
        self.url = f"tcp://127.0.0.1:{self.port}"
        self.cmd = ["qemu-system-arm", "-M", "stm32vldiscovery", "-nographic",
                    "-monitor", "none", "-no-reboot",
                    "-device", f"loader,file={image},addr=0x{FLASH_BASE:08x}",
                    "-device", f"loader,file={erased},addr=0x{staging:08x}",
                    "-serial", f"tcp:127.0.0.1:{self.port},server=on,wait=off,nodelay=on",
                    *extra]
        self.output = None
        self.proc = subprocess.Popen(self.cmd, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT)

    def wait_ready(self, timeout=10.0):
        """Until the application answers PING ID 1 on the socket (it boots through the
        bootloader's image check); False on timeout or if QEMU exited."""
        t0 = time.monotonic()
        while time.monotonic() - t0 < timeout and self.proc.poll() is None:
            try:
                with socket.create_connection(("127.0.0.1", self.port), timeout=1) as s:
                    s.settimeout(0.3)
                    while time.monotonic() - t0 < timeout:
                        s.sendall(PING)
                        try:
                            if s.recv(16):
                                time.sleep(0.05)  # the rest of the answer, then close
                                return True
                        except socket.timeout:
                            pass
            except OSError:
                time.sleep(0.05)
        return False

    def alive(self):
        return self.proc.poll() is None

    def stop(self):
        """Kill QEMU; what it printed (empty if nothing). Once is enough."""
        if self.output is None:
            if self.proc.poll() is None:
                self.proc.kill()
            self.output = self.proc.communicate(timeout=5)[0].decode(errors="replace").strip()
            self.tmp.cleanup()
        return self.output

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--port", type=int, default=0, help="TCP port of USART1 (default: free)")
    ap.add_argument("--uid", type=bytes.fromhex, default=None,
                    help="the instance's unique ID, 24 hex digits (default: 12 zero bytes)")
    ap.add_argument("image", nargs="?", default=IMAGE)
    ap.add_argument("elf", nargs="?", default=ELF)
    a = ap.parse_args()
    q = QemuServo(a.image, a.elf, a.port or None, uid=a.uid)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    try:
        if not q.wait_ready():
            sys.exit("qemu: the image did not answer PING within 10 s: %s" % q.stop())
        print(" ".join(q.cmd))
        print("The arm (ID 1, 9600 baud, factory settings) runs on QEMU's "
              "stm32vldiscovery; USART1 is the bus:")
        print(f"  servoctl --port {q.url} scan")
        print(f"  (or PYTHONPATH=tools/python /usr/bin/python3 -m servobus --port {q.url} scan;"
              " on a heavily loaded machine add --timeout 1: QEMU runs in host time)")
        print("Ctrl-C stops it.", flush=True)
        q.proc.wait()
        sys.exit("qemu: QEMU exited (%d): %s" % (q.proc.returncode, q.stop()))
    except KeyboardInterrupt:
        print()
    finally:
        q.stop()


if __name__ == "__main__":
    main()
