#!/usr/bin/env python3
"""bench_studio.py [BUILD_DIR] - Servo Studio's live polling (issue 29) against servo-sim
through its baud model (rfc2217://: the host's bytes take their wire time too): the
rate the dashboard (one READ of registers 36-46 per servo) and the plot of any register
(present speed, position and temperature of every servo: one READ of 38-46 each) hold
with three servos (arm, foot, base; factory return delays), at 9600 baud and at 921600
(the table's nearest to 1 Mbaud), against the wire's limit for the READs they need
(servobus/polling.py). The studio's own poller (servobus/studio/live.py) runs the
cycles, paced as its worker paces them (at most SAMPLE_HZ a second)."""

import os
import sys
import time
import types

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools", "python"))
sys.path.insert(0, os.path.join(ROOT, "tools"))

from bench_sim import start_sim, stop_sim  # noqa: E402
from servobus import BROADCAST, Bus  # noqa: E402
from servobus.registers import BAUD_RATES  # noqa: E402
from servobus.studio.live import Live  # noqa: E402
from servobus.studio.worker import SAMPLE_HZ  # noqa: E402

SERVOS = ("1:arm", "2:foot", "3:base")
RUN_S = 4.0
BAUDS = ((None, 9600), (8, 921600))


def measure(bus, servos, what):
    """Run the studio's poller for RUN_S: (cycles a second held, the wire's limit)."""
    pushed = []
    st = types.SimpleNamespace(state={"servos": servos}, resolutions={},
                               t0=time.monotonic(), push=pushed.append)
    live = Live(st)
    if what == "dash":
        live.dash_on = True
    else:
        live.set_picks("bench", {s["id"]: ["present_speed", "present_temperature",
                                           "present_position"
                                           if s["variant"] in ("wrist", "finger")
                                           else "turned_angle"] for s in servos}, bus.baud)
    period, start = 1.0 / SAMPLE_HZ, time.monotonic()
    nxt, cycles = start, 0
    live.poll(bus)  # the first cycle reads the slow registers too: not counted
    start = nxt = time.monotonic()
    while time.monotonic() - start < RUN_S:
        time.sleep(max(0.0, nxt - time.monotonic()))
        nxt = max(nxt + period, time.monotonic() - period)
        live.poll(bus)
        cycles += 1
    held = cycles / (time.monotonic() - start)
    return held, pushed[-1]["wire_hz"], (pushed[-1].get("reads") or len(servos))


def main():
    build = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build", "bench")
    sim = os.path.join(build, "servo-sim")
    if not os.access(sim, os.X_OK):
        sim = os.path.join(ROOT, "build", "host", "servo-sim")
    p, url = start_sim(sim, SERVOS)
    with Bus(url) as raw:  # raw tcp:// reaches every servo whatever its baud: all at 9600
        raw.write(BROADCAST, {"baud_rate": BAUD_RATES.index(9600) + 1})
    time.sleep(0.1)
    url = url.replace("tcp://", "rfc2217://")
    print("\n== Servo Studio's live polling, servo-sim through its baud model (rfc2217),")
    print("   three servos (arm, foot, base), factory return delays, %.0f s each" % RUN_S)
    print("%-40s %10s %12s %9s" % ("", "held", "wire limit", "held/wire"))
    try:
        with Bus(url, baud=9600) as bus:
            found = {f.id: f for f in bus.scan()}
            if len(found) != len(SERVOS):
                sys.exit("bench_studio: %d servos answer at 9600 baud, not %d" % (
                    len(found), len(SERVOS)))
            servos = [{"id": i, "model": bus.read(i, "model_number"),
                       "variant": bus.variant(i).name} for i in sorted(found)]
            for code, baud in BAUDS:
                if code is not None:
                    bus.write(BROADCAST, {"baud_rate": code})
                    time.sleep(0.1)
                    bus.set_baud(baud)
                for what, label in (("dash", "dashboard (36-46, 3 READs)"),
                                    ("scope", "plot: 3 registers x 3 servos")):
                    held, wire, reads = measure(bus, servos, what)
                    print("%-40s %7.1f Hz %9.1f Hz %8.0f %%" % (
                        "%6d baud, %s" % (baud, label), held, wire, 100 * held / wire))
            bus.write(BROADCAST, {"baud_rate": 0})
    finally:
        stop_sim(p)
    print("(wire limit = 1 / the sum over the READs of a cycle of (request + answer bytes)\n"
          " x 10 bits / baud + the servo's return delay; the studio caps its cycles at %d a\n"
          " second, so at 921600 baud the cap, not the wire, sets the rate)" % SAMPLE_HZ)


if __name__ == "__main__":
    main()
