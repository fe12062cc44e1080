#!/usr/bin/env python3
"""bench_sim.py [BUILD_DIR] - servo-sim benchmarks through the Python SDK (real time):

1. A full bus (253 servos, IDs 1-253): one broadcast scan against pinging the IDs one
   by one, at 9600 baud with the factory return delay and at 1,792,000 baud with none.
2. Round-trip latency of a PING through servo-sim, against the wire time it models.
3. Firmware update (PROTOCOL.md §10) of a 16 KiB image at 115200 baud and at 921600
   baud (code 8, the table's nearest to 1 Mbaud), against the wire time of its bytes.

BUILD_DIR holds servo-sim (default build/bench, else build/host). Called by
tools/bench.sh (make bench)."""

import os
import signal
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools", "python"))

from servobus import BROADCAST, Bus  # noqa: E402
from servobus import image as I  # noqa: E402
from servobus import protocol as P  # noqa: E402

FAST_BAUD_CODE, FAST_BAUD = 10, 1792000
# Update benchmark: register 4 codes. ~1 Mbaud: 921600 (code 8) is the nearest of §5.2.
UPDATE_BAUDS = ((4, 115200), (8, 921600))
UPDATE_BYTES = 16 * 1024


def start_sim(sim, servos):
    args = [sim, "--listen", "127.0.0.1:0"]
    for s in servos:
        args += ["--servo", s]
    p = subprocess.Popen(args, stdout=subprocess.PIPE, text=True)
    line = p.stdout.readline()
    if "listening on" not in line:
        p.kill()
        sys.exit("bench_sim: servo-sim did not start")
    port = int(line.split("127.0.0.1:")[1].split()[0])
    return p, "tcp://127.0.0.1:%d" % port


def stop_sim(p):
    p.send_signal(signal.SIGTERM)
    p.wait(timeout=10)
    p.stdout.close()


def last_answer_time(bus, expect):
    """Seconds from a broadcast PING until the last of `expect` answers has arrived."""
    sent = bus.send(BROADCAST, P.PING)
    t0 = time.monotonic()
    parser, got = P.StatusParser(), set()
    deadline = t0 + bus.scan_window() + 1.0
    while len(got) < expect and time.monotonic() < deadline:
        for pkt in parser.feed(bus._t.read(deadline)):
            if pkt.raw != sent and pkt.ok:
                got.add(pkt.id)
    return time.monotonic() - t0, len(got)


def full_bus(bus, ids, label, model_s):
    t0 = time.monotonic()
    found = bus.scan()
    scan_s = time.monotonic() - t0
    last_s, n_last = last_answer_time(bus, len(ids))
    t0 = time.monotonic()
    for i in ids:
        bus.ping(i)
    one_s = time.monotonic() - t0
    assert [f.id for f in found] == ids and n_last == len(ids), "scan missed servos"
    print("%-28s %8.3f s %9.3f s %10.3f s %7.1fx %7.1fx" % (
        label, scan_s, last_s, one_s, one_s / scan_s, one_s / last_s))
    print("%-28s %8s %9.3f s (the wire: return delay + 254 answer slots)" % (
        "", "", model_s))
    return found


def latency(bus, servo_id, n):
    rtts = []
    for _ in range(n):
        t0 = time.perf_counter()
        bus.ping(servo_id)
        rtts.append(time.perf_counter() - t0)
    rtts.sort()
    return (statistics.median(rtts), rtts[int(0.9 * (n - 1))], rtts[-1])


def main():
    build = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build", "bench")
    sim = os.path.join(build, "servo-sim")
    if not os.access(sim, os.X_OK):
        sim = os.path.join(ROOT, "build", "host", "servo-sim")
    if not os.access(sim, os.X_OK):
        sys.exit("bench_sim: no servo-sim in %s or build/host: build it first" % build)

    print("\n== servo-sim (%s), real time, through the Python SDK" % os.path.relpath(sim, ROOT))
    ids = list(range(1, 254))
    p, url = start_sim(sim, ["%d:arm" % i for i in ids])
    try:
        with Bus(url) as bus:
            print("full bus of %d servos: broadcast scan vs pinging the IDs one by one" %
                  len(ids))
            print("%-28s %10s %11s %12s %8s %8s" % ("", "scan (SDK)", "last answer",
                                                     "one by one", "ratio", "ratio*"))
            slot = P.SLOT_BYTES * 10.0
            full_bus(bus, ids, "9600 baud, delay 8 ms",
                     0.008 + 254 * slot / 9600)
            bus.write(BROADCAST, {"baud_rate": FAST_BAUD_CODE, "return_delay": 0})
            bus.set_baud(FAST_BAUD)
            time.sleep(0.2)
            full_bus(bus, ids, "%d baud, delay 0" % FAST_BAUD, 254 * slot / FAST_BAUD)
            print("(ratio = one by one / SDK scan, which also listens for the longest "
                  "return delay, 127.5 ms;\n ratio* = one by one / time to the last answer)")
            # A sparse bus: pinging one by one waits the SDK's time-out for every absent ID.
            for baud in (9600, FAST_BAUD):
                bus.set_baud(baud)
                absent = len(ids) - 3
                print("sparse bus, 3 servos, %7d baud: one by one ~ %d x %.0f ms time-out = "
                      "%.0f s, %.0fx the scan (estimate)" % (
                          baud, absent, bus.answer_timeout() * 1e3,
                          absent * bus.answer_timeout(),
                          absent * bus.answer_timeout() / bus.scan_window()))
    finally:
        stop_sim(p)

    p, url = start_sim(sim, ["1:arm"])
    try:
        with Bus(url) as bus:
            print()
            print("round trip of a PING (7 bytes out, 7 back) through servo-sim "
                  "(200 at 9600 baud, 500 at 1,792,000):")
            print("%-28s %9s %9s %9s %12s" % ("", "median", "p90", "max", "the wire"))
            wire = 0.008 + 7 * 10 / 9600
            med, p90, worst = latency(bus, 1, 200)
            print("%-28s %7.2f ms %6.2f ms %6.2f ms %9.2f ms" % (
                "9600 baud, delay 8 ms", med * 1e3, p90 * 1e3, worst * 1e3, wire * 1e3))
            bus.write(1, {"baud_rate": FAST_BAUD_CODE, "return_delay": 0})
            bus.set_baud(FAST_BAUD)
            time.sleep(0.05)
            wire = 7 * 10 / FAST_BAUD
            med, p90, worst = latency(bus, 1, 500)
            print("%-28s %7.3f ms %6.3f ms %6.3f ms %9.3f ms" % (
                "%d baud, delay 0" % FAST_BAUD, med * 1e3, p90 * 1e3, worst * 1e3,
                wire * 1e3))
            print("(the host's 7 bytes take no wire time over TCP; beyond the wire, the "
                  "latency is\n servo-sim's main loop, loopback TCP and the Python SDK)")
    finally:
        stop_sim(p)

    update_bench(sim)


def pace_host(bus, baud):
    """Make the host's writes take their wire time, as on a serial port (write, then
    drain): each frame reaches servo-sim when its last stop bit would have."""
    write = bus._t.write

    def paced(data):
        time.sleep(len(data) * 10.0 / baud)
        write(data)
    bus._t.write = paced


def one_update(sim, code, baud, delay, version, paced):
    p, url = start_sim(sim, ["1:arm"])
    try:
        with Bus(url) as bus:
            bus.write(1, {"baud_rate": code, "return_delay": delay})
            bus.set_baud(baud)
            time.sleep(0.05)
            if paced:
                pace_host(bus, baud)
            image = I.build(UPDATE_BYTES, version, I.MODELS["arm"], seed=version)
            assert bus.update(1, image, notify=lambda text: None) == version
            return bus.update_stats
    finally:
        stop_sim(p)


def update_bench(sim):
    """Bus.update() of a 16 KiB image through servo-sim: the transfer (enter to the
    end-of-batch answer) against the wire time of its bytes, both directions."""
    print()
    print("firmware update of a %d KiB image (%d data blocks, 1036-byte frames), servo-sim arm"
          % (UPDATE_BYTES // 1024, UPDATE_BYTES // 1024))
    print("%-26s %9s %9s %9s %7s %9s %7s" % ("", "as is", "paced", "wire", "ratio",
                                             "restart", "bytes"))
    version = 1
    for code, baud in UPDATE_BAUDS:
        for delay in (0, 16):
            version += 1
            raw = one_update(sim, code, baud, delay, version, paced=False)
            version += 1
            st = one_update(sim, code, baud, delay, version, paced=True)
            nbytes = st.bytes_out + st.bytes_in
            wire = nbytes * 10.0 / baud
            print("%-26s %7.3f s %7.3f s %7.3f s %6.2fx %7.3f s %7d%s" % (
                "%d baud, delay %g ms" % (baud, delay / 2.0), raw.transfer_s, st.transfer_s,
                wire, st.transfer_s / wire, st.restart_s, nbytes,
                "  (%d frames resent)" % (st.resent + raw.resent)
                if st.resent or raw.resent else ""))
    print("(wire = bytes both ways x 10 bits / baud: the limit; ratio = paced / wire.\n"
          " as is: servo-sim takes the host's bytes in no wire time (it paces only the\n"
          " answers), so it beats the wire; paced: the bench delays each frame by its wire\n"
          " time, as a serial port does. delay = return delay (register 5; 8 ms is the arm's\n"
          " factory value), paid once per frame, 20 frames. restart = end-of-batch answer\n"
          " to the version read of the restarted servo)")


if __name__ == "__main__":
    main()
