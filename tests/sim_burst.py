#!/usr/bin/python3
"""sim_burst.py - servo-sim's raw (tcp://) clients meet the bus a real host would
(issue 25, "no frame is dropped silently"): a burst sent in one socket write reaches
each servo paced at its baud, as from a UART, so the servos keep up as on hardware.

  distinct  8 servos (IDs 1-8, feet) at 9600 baud; one socket write of 24 SYNC WRITEs,
            each giving one servo's speed, acceleration or deceleration a value of its
            own; then every servo's table is read back: all 24 applied
  storm     the same servos at 1792000 baud; one socket write of 400 broadcast WRITEs of
            the acceleration (1, 2, ... cycling); every servo reads the last value
Neither may make servo-sim report a dropped frame (`servo-sim: ID n dropped ...` on
stderr, the receiver's overruns).

Usage: sim_burst.py [path/to/servo-sim]   (default build/host/servo-sim; $SERVO_SIM)
"""
import os
import socket
import subprocess
import sys
import time

from rawbus import connect, packet, reporter

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
NAME = "sim_burst"
IDS = range(1, 9)
SPEED, ACC, DEC = 32, 34, 35


fail, say = reporter(NAME)


class Sim:
    def __init__(self, exe):
        args = [exe, "--listen", "127.0.0.1:0"]
        for i in IDS:
            args += ["--servo", f"{i}:foot"]
        self.proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True)
        line = self.proc.stdout.readline()
        if "listening on" not in line:
            fail(f"servo-sim did not start: {line!r}")
        port = int(line.split()[3].rsplit(":", 1)[1])
        self.sock = connect(port, timeout=5)
        self.sock.settimeout(0.05)

    def drain(self):
        got = b""
        while True:
            try:
                chunk = self.sock.recv(4096)
            except socket.timeout:
                return got
            if not chunk:
                fail("servo-sim closed the connection")
            got += chunk

    def ask(self, pkt, n_data, timeout=1.0):
        """Send pkt; the data of its answer (n_data bytes), ERR 0, or fail."""
        self.drain()
        self.sock.sendall(pkt)
        got, want, end = b"", 6 + n_data, time.monotonic() + timeout
        while len(got) < want and time.monotonic() < end:
            try:
                got += self.sock.recv(want - len(got))
            except socket.timeout:
                pass
        if len(got) != want or got[:3] != bytes([0xD5, 0x5D, pkt[2]]) or got[4] != 0:
            fail(f"{pkt.hex(' ')} answered {got.hex(' ') or 'nothing'}")
        return got[5:5 + n_data]

    def cells(self, sid):
        d = self.ask(packet(sid, 0x02, SPEED, 4), 4)
        return [d[0] | d[1] << 8, d[2], d[3]]

    def stop(self):
        self.sock.close()
        self.proc.terminate()
        _, err = self.proc.communicate(timeout=5)
        return err


def main():
    exe = (sys.argv[1] if len(sys.argv) > 1 else
           os.environ.get("SERVO_SIM", os.path.join(REPO, "build", "host", "servo-sim")))
    sim = Sim(exe)
    try:
        # 24 SYNC WRITEs, one cell each, in one write at the factory 9600 baud.
        want = {i: [100 + i, 10 + i, 20 + i] for i in IDS}
        burst = b""
        for c, (reg, size) in enumerate(((SPEED, 2), (ACC, 1), (DEC, 1))):
            for i in IDS:
                v = want[i][c]
                burst += packet(0xFE, 0x83, reg, size, i, *([v & 0xFF, v >> 8][:size]))
        t0 = time.monotonic()
        sim.sock.sendall(burst)
        time.sleep(len(burst) * 10 / 9600 + 0.1)  # its wire time, and then some
        for i in IDS:
            got = sim.cells(i)
            if got != want[i]:
                fail(f"24 SYNC WRITEs in one write at 9600 baud: ID {i} reads {got}, "
                     f"expected {want[i]}")
        say(f"24 SYNC WRITEs ({len(burst)} bytes) in one socket write at 9600 baud: all "
            f"applied ({time.monotonic() - t0:.2f} s)")

        # 400 broadcast WRITEs in one write at 1792000 baud.
        for i in IDS:
            sim.ask(packet(i, 0x03, 4, 10), 0)  # baud code 10, answered at 9600
        time.sleep(0.05)
        storm = b"".join(packet(0xFE, 0x03, ACC, 1 + k % 250) for k in range(400))
        sim.sock.sendall(storm)
        time.sleep(0.2)
        for i in IDS:
            got = sim.cells(i)[1]
            if got != 1 + 399 % 250:
                fail(f"400 broadcast WRITEs in one write at 1792000 baud: ID {i} reads "
                     f"acceleration {got}, expected {1 + 399 % 250} (the last)")
        say(f"400 broadcast WRITEs ({len(storm)} bytes) in one socket write at 1792000 "
            "baud: the last one applied on every servo")
    finally:
        err = sim.stop()
    dropped = [line for line in err.splitlines() if "dropped" in line]
    if dropped:
        fail("servo-sim reported dropped frames: " + "; ".join(dropped))
    say("PASS: no frame dropped")


if __name__ == "__main__":
    main()
