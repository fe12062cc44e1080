#!/usr/bin/env python3
"""bench_ids.py [BUILD_DIR] - issue 27: time to enumerate and to separate a bus of N
servos that all sit at ID 1 (factory-fresh), N = 10, 50, 253, at 9600 and at 921600 baud
(code 8, the table's nearest to 1 Mbaud), through servo-sim and the SDK in real time,
against the wire time of the frames it needs (every byte sent and received, plus the
ENUMERATE answer windows, which a host must wait out whether or not a slot answers).
BUILD_DIR holds servo-sim (default build/bench, else build/host). Called by
tools/bench.sh (make bench). IDS_BENCH_N=10,50 limits the sizes."""

import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools", "python"))

from servobus import Bus  # noqa: E402
from servobus import ids as ID  # noqa: E402
from servobus import protocol as P  # noqa: E402
from servobus.registers import BAUD_RATES  # noqa: E402


def start_sim(sim, n):
    args = [sim, "--listen", "127.0.0.1:0"] + ["--servo", "1:foot"] * n
    p = subprocess.Popen(args, stdout=subprocess.PIPE, text=True)
    line = p.stdout.readline()
    if "listening on" not in line:
        p.kill()
        raise SystemExit("servo-sim did not start: " + line)
    port = int(line.split("listening on ")[1].split()[0].rsplit(":", 1)[1])
    return p, "tcp://127.0.0.1:%d" % port


class Counting:
    """Bytes each way through a Bus's tap, and the ENUMERATE windows asked."""

    def __init__(self, bus):
        self.tx = self.rx = 0
        bus.tap = self.tap

    def tap(self, direction, data, _t):
        if direction == "tx":
            self.tx += len(data)
        else:
            self.rx += len(data)


def run(sim, n, baud):
    p, url = start_sim(sim, n)
    try:
        if baud != 9600:
            with Bus(url) as b:
                b.send(P.BROADCAST, P.WRITE, bytes([4, BAUD_RATES.index(baud) + 1]))
                b.pause(0.3)
        with Bus(url, baud=baud) as bus:
            c = Counting(bus)
            t0 = time.monotonic()
            found = bus.enumerate()
            t_enum = time.monotonic() - t0
            rounds = bus.enumerate_rounds
            enum_wire = c.tx * P.byte_time(baud) + rounds * (
                ID.TURNAROUND_S + ID.SLOTS * ID.slot_time(baud))
            tx0, rx0 = c.tx, c.rx
            t1 = time.monotonic()
            moves = bus.fix_duplicates(found)
            t_fix = time.monotonic() - t1
            fix_rounds = bus.enumerate_rounds
            fix_wire = (c.tx - tx0) * P.byte_time(baud) + fix_rounds * (
                ID.TURNAROUND_S + ID.SLOTS * ID.slot_time(baud))
            ids = sorted(i.id for i in bus.enumerate())
            ok = len(found) == n and ids == list(range(1, n + 1))
        print("%3d servos at ID 1, %6d baud: enumerate %6.2f s (%3d rounds, wire %6.2f s); "
              "fix %6.2f s (%3d IDs written, wire %6.2f s)%s" % (
                  n, baud, t_enum, rounds, enum_wire, t_fix, len(moves), fix_wire,
                  "" if ok else "  !! NOT ALL SEPARATED"))
        return ok
    finally:
        p.terminate()
        p.wait()


def main():
    build = sys.argv[1] if len(sys.argv) > 1 else "build/bench"
    sim = os.path.join(build, "servo-sim")
    if not os.access(sim, os.X_OK):
        sim = os.path.join("build", "host", "servo-sim")
    sizes = [int(x) for x in os.environ.get("IDS_BENCH_N", "10,50,253").split(",")]
    print("== issue 27: enumerate and separate N factory-fresh servos (all at ID 1) on servo-sim")
    ok = True
    for baud in (9600, 921600):
        for n in sizes:
            ok &= run(sim, n, baud)
    if not ok:
        print("!! not every bus was separated: servo-sim runs every servo in real time, and "
              "a loaded host falls behind a large bus (its answers then come late)")
    return 0  # a figure, like the other bench lines: make bench goes on


if __name__ == "__main__":
    sys.exit(main())
