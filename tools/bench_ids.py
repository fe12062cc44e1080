#!/usr/bin/env python3
"""bench_ids.py [BUILD_DIR] - issue 27: time to enumerate and to separate a bus of N
servos that all sit at ID 1 (factory-fresh), N = 10, 50, 253, at 9600 and at 921600 baud
(code 8, the table's nearest to 1 Mbaud), through servo-sim and the SDK in real time,
against the wire time of the frames it needs (every byte sent and received, plus the
ENUMERATE answer windows, which a host must wait out whether or not a slot answers).
First, on a mixed bus (host nodes, and QEMU arm images when build/qemu has them), the
coordinated start skew of a SYNC WRITE and of a broadcast ACTION, and the end skew of one
trajectory loaded and started in every servo by broadcast (limit: one control tick for
host nodes, which share servo-sim's virtual clock; see trajectory()).
BUILD_DIR holds servo-sim (default build/bench, else build/host). Called by
tools/bench.sh (make bench). IDS_BENCH_N=10,50 limits the sizes."""

import os
import re
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools", "python"))

from servobus import Bus  # noqa: E402
from servobus import ids as ID  # noqa: E402
from servobus import protocol as P  # noqa: E402
from servobus.registers import BAUD_RATES  # noqa: E402

sys.path.insert(0, os.path.join(ROOT, "tools"))
TICK_US = 1000  # the control tick (include/motion.h MOTION_TICK_US)
# How late the ACTION frame may leave after the host's clock was read before sending it,
# plus the tick the host nodes wait to start on: the real-to-virtual anchor's error.
ANCHOR_US = 3000
MOVE = re.compile(r"servo-sim: ID (\d+) moving (\d) at (\d+) us")
QEMU_UIDS = ("a1000000000000000000000e", "b2000000000000000000000e")
# The trajectory every servo runs (angle in position units, speed in units/s): from the
# homed end (420 on the arm) down through 300 to 150 without a stop, a reversal, then 250.
TRAJECTORY = [(300, 120), (150, 120), (250, 60)]


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


def host_switches(path, ids, to, since):
    """{ID: virtual time (us)} of each host node's first switch of register 42 to `to`
    after line `since` of servo-sim's --report-moves log; and the log's length."""
    with open(path) as f:
        lines = f.read().splitlines()
    at = {}
    for line in lines[since:]:
        m = MOVE.match(line)
        if m and int(m.group(1)) in ids and int(m.group(2)) == to:
            at.setdefault(int(m.group(1)), int(m.group(3)))
    return at, len(lines)


def bracketed(bus, ids, to, timeout=15.0):
    """{ID: (lo, hi)} in real time (s): servo ID's register 42 switched to `to` after lo,
    the time just before the last READ that still gave the other value was sent (or
    polling began), and before hi, the time just after the first READ that gave `to` was
    answered. Each servo not yet switched is read in turn: a bracket is about one poll
    cycle wide."""
    lo, at = {i: time.monotonic() for i in ids}, {}
    t_end = time.monotonic() + timeout
    while len(at) < len(ids) and time.monotonic() < t_end:
        for i in ids:
            if i in at:
                continue
            before = time.monotonic()
            if bus.read(i, "moving") == to:
                at[i] = (lo[i], time.monotonic())
            else:
                lo[i] = before
    return at


def anchored(bus, send):
    """Run send() (which puts frames on the bus) and return (t, us): t the real time just
    before, us the wire time of the last frame it sent. Host nodes that a frame starts
    begin on the first tick after its end, so for their virtual start v the virtual clock
    reads real time + c, with v - (t * 1e6 + us) - ANCHOR_US <= c <= v - (t * 1e6 + us)."""
    last, tap = [], bus.tap
    bus.tap = lambda d, data, t: last.append(data) if d == "tx" else None
    try:
        t = time.monotonic()
        send()
    finally:
        bus.tap = tap
    return t, len(last[-1]) * P.byte_time(bus.baud or 9600) * 1e6


def on_virtual(polled, c_hi):
    """Brackets {ID: (lo, hi)} in real time (s) onto the virtual clock (us)."""
    return {i: (lo * 1e6 + c_hi - ANCHOR_US, hi * 1e6 + c_hi) for i, (lo, hi) in polled.items()}


def all_ends(polled, c_hi, host_ended):
    """The end skew of all servos: (least, most, widest bracket, host IDs whose exact end
    is outside their own polled bracket), in us; host nodes exact where known."""
    ends = on_virtual(polled, c_hi)
    missed = [i for i, t in host_ended.items() if i in ends and not ends[i][0] <= t <= ends[i][1]]
    width = max(b - a for a, b in ends.values())
    ends.update({i: (t, t) for i, t in host_ended.items()})
    least, most = skew_bounds(ends)
    return least, most, width, missed


def ms_range(least, most):
    return "%d..%d ms" % (least // 1000, -(-most // 1000))


def skew_bounds(ends):
    """(least, most) skew (us) that ends {ID: (earliest, latest)} allow."""
    return (max(0, max(a for a, _ in ends.values()) - min(b for _, b in ends.values())),
            max(b for _, b in ends.values()) - min(a for a, _ in ends.values()))


def homed(bus, log, host_ids, qemu_ids, timeout=40.0):
    """Home every servo by one broadcast: {ID: state of register 24}, 2 done, 3 failed.
    The host nodes are not addressed until their homing is over (servo-sim's log shows
    register 42 back at 0): an answer holds a node's loop for microseconds, enough to
    change where it comes to rest, and the trajectory's end skew needs every host node
    to start it from the same state. The QEMU images are polled (register 24). The
    heartbeat is off in this bench: else a servo not addressed for 500 ms would abort
    its homing (section 9)."""
    _, n = host_switches(log, host_ids, 1, 0)
    bus.send(P.BROADCAST, P.WRITE, bytes([24, 1]))  # homing; also leaves speed mode
    state, t_end = {}, time.monotonic() + timeout
    while time.monotonic() < t_end:
        for i in qemu_ids:
            if i not in state and bus.read(i, "homing") >> 4 in (2, 3):
                state[i] = bus.read(i, "homing") >> 4
        began, _ = host_switches(log, host_ids, 1, n)
        ended, _ = host_switches(log, host_ids, 0, n)
        if len(began) == len(ended) == len(host_ids) and len(state) == len(qemu_ids):
            break
        time.sleep(0.1)
    for i in host_ids:
        state[i] = bus.read(i, "homing") >> 4
    return state


def trajectory(bus, log, host_ids, qemu_ids):
    """Issue 27's trajectory end skew: every servo (speed mode left by coordinated()) is
    homed by one broadcast (position moves need the reference, register 49), which leaves
    them all at the end of their travel; then one broadcast TRAJECTORY WRITE stores the
    same points in every servo and one broadcast TRAJECTORY ACTION runs them. Register 42
    stays 1 for the whole trajectory (it passes through points and stops at reversals
    within one run), so its first switch to 0 after the start is the trajectory's end.

    The limit, for host nodes: they share servo-sim's virtual clock and every one hears
    the broadcast's last stop bit at the same instant, so each starts on its next control
    tick (start skew <= 1 tick); each then runs the same firmware, plant and points from
    the same homed state, tick by tick, so its run lasts the same whole number of ticks
    and the end skew is at most the start skew: 1 tick. That holds while nothing else
    differs between them, so the host does not address a host node during that run (the
    QEMU images, on QEMU's own clock and seen from the bus only, are polled).

    The images' starts and ends are bracketed by READs (bracketed()) and placed on the
    virtual clock (servo-sim's is CLOCK_MONOTONIC, as time.monotonic()) by the ACTION
    frame: the host nodes started on the first tick after it. All servos' end skew is
    then a range, its width the poll's.

    The run is then repeated with every servo polled, as a host watching its servos
    would: each answer holds its node's main loop up to BUS_LOOP_US + 1/16 bit
    (tools/sim/bus.c), its ticks sample the plant microseconds late, and the settle that
    ends register 42 (the shaft at rest within the hold band) moves by whole ticks. That
    figure is printed without a limit; there the host nodes' exact ends must also fall
    in their own polled brackets, which checks the clock anchor."""
    ids = sorted(host_ids + qemu_ids)
    state = homed(bus, log, host_ids, qemu_ids)
    if sorted(i for i, st in state.items() if st == 2) != ids:
        print("!! trajectory: homing not done on every servo: %s" % (
            {i: state.get(i, "timed out") for i in ids},))
        return False
    bus.trajectory_write(P.BROADCAST, TRAJECTORY)
    bus.pause(0.1)
    ok = True
    for quiet in (True, False):
        _, n = host_switches(log, host_ids, 1, 0)
        sent, frame_us = anchored(bus, lambda: bus.trajectory_action(P.BROADCAST))
        polled_start = bracketed(bus, qemu_ids, 1, timeout=2.0) if quiet else {}
        polled = bracketed(bus, qemu_ids if quiet else ids, 0)
        t_end = time.monotonic() + 15.0
        while len(host_switches(log, host_ids, 0, n)[0]) < len(host_ids) and \
                time.monotonic() < t_end:
            time.sleep(0.2)  # watching servo-sim's log: the bus stays quiet
        bus.pause(0.2)
        began, _ = host_switches(log, host_ids, 1, n)
        ended, _ = host_switches(log, host_ids, 0, n)
        ok &= len(began) == len(ended) == len(host_ids) and \
            len(polled) == len(qemu_ids if quiet else ids)
        if not (len(began) == len(ended) == len(host_ids)):
            continue
        start = max(began.values()) - min(began.values())
        skew = max(ended.values()) - min(ended.values())
        run_s = (min(ended.values()) - min(began.values())) / 1e6
        if quiet:
            over = start > TICK_US or skew > TICK_US
            ok &= not over
            print("bench ids: trajectory end skew %d us, %d points by broadcast TRAJECTORY "
                  "WRITE + TRAJECTORY ACTION (%d host nodes, virtual clock, not addressed "
                  "during the %.3f s run; start skew %d us; limit 1 tick = %d us)%s" % (
                      skew, len(TRAJECTORY), len(host_ids), run_s, start, TICK_US,
                      "  !! OVER" if over else ""))
        else:
            print("bench ids: trajectory end skew %d us with every servo polled during the "
                  "%.3f s run (%d host nodes, virtual clock; start skew %d us; no limit: "
                  "each answer delays its node's ticks by microseconds, which moves the "
                  "settle)" % (skew, run_s, len(host_ids), start))
        if len(polled) != len(qemu_ids if quiet else ids) or not polled:
            continue
        # Real time onto servo-sim's virtual clock (both CLOCK_MONOTONIC): the host nodes
        # started on the first tick after the ACTION frame's end, which left at `sent` or
        # up to ANCHOR_US later (the write, TCP, that tick): virtual = real + c, with c
        # between c_hi - ANCHOR_US and c_hi.
        c_hi = min(began.values()) - (sent * 1e6 + frame_us)
        if quiet:  # each image against the host nodes: when it started, when it ended
            t0, t1 = min(began.values()), min(ended.values())
            starts, ends = on_virtual(polled_start, c_hi), on_virtual(polled, c_hi)
            for i in qemu_ids:
                print("bench ids: QEMU image ID %d: trajectory %s, ended %+d..%+d ms from the "
                      "host nodes (polled)" % (
                          i, "started %+d..%+d ms from the host nodes" % (
                              (starts[i][0] - t0) // 1000, -(-(starts[i][1] - t0) // 1000))
                          if i in starts else "start not seen",
                          (ends[i][0] - t1) // 1000, -(-(ends[i][1] - t1) // 1000)))
        least, most, width, missed = all_ends(polled, c_hi, ended)
        print("bench ids: trajectory end skew %s across all %d servos, %d on QEMU (%s; "
              "polled ends placed on the virtual clock by the ACTION frame, each within %d "
              "ms)%s" % (
                  ms_range(least, most), len(ids), len(qemu_ids),
                  "host nodes exact, the images polled" if quiet else "every servo polled",
                  -(-width // 1000),
                  "  !! host node(s) %s outside their polled bracket: anchor off" % missed
                  if missed else ""))
        ok &= not missed
    if not ok:
        print("!! trajectory: not every servo ran it to its end, or host nodes over 1 tick "
              "(see above)")
    return ok


def coordinated(sim):
    """Issue 27's coordinated start on the mixed bus: host nodes and (when the qemu image
    is built) QEMU-run arm images, all at ID 1, separated by fix_duplicates, then in speed
    mode (angle limits 0, register 49 = 1: no homing needed; heartbeat off) started by one SYNC WRITE
    and by REG WRITE + one broadcast ACTION, and stopped the other way. Host nodes report
    register 42's switches in virtual time (--report-moves): the skew between them is
    exact. The images are seen from the bus only: their stop is polled. Then a trajectory
    on all of them (trajectory(): homed, one broadcast TRAJECTORY WRITE and ACTION) for
    its end skew."""
    qemus, log = [], tempfile.NamedTemporaryFile("w+", suffix=".log", delete=False)
    try:
        try:
            from qemu_servo import QemuServo
            qemus = [QemuServo(uid=bytes.fromhex(u)) for u in QEMU_UIDS]
            if not all(q.wait_ready() for q in qemus):
                raise RuntimeError("an image did not answer PING")
            why = ""
        except (OSError, RuntimeError) as e:
            for q in qemus:
                q.stop()
            qemus, why = [], str(e).splitlines()[0] if str(e) else type(e).__name__
        args = [sim, "--listen", "127.0.0.1:0", "--report-moves"] + ["--servo", "1:arm"] * 4
        for q in qemus:
            args += ["--uart", "127.0.0.1:%d" % q.port]
        p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=log, text=True)
        line = p.stdout.readline()
        url = "tcp://127.0.0.1:%d" % int(line.split("listening on ")[1].split()[0].rsplit(":", 1)[1])
        print("== coordinated start (issue 27) on a mixed bus: 4 host nodes + %s" % (
            "%d QEMU arm images (servo-sim --uart)" % len(qemus) if qemus else
            "NO QEMU image (%s): host nodes only" % (why or "build/qemu not built")))
        try:
            with Bus(url, timeout=1.5) as bus:
                bus.fix_duplicates(bus.enumerate())
                idents = bus.enumerate()
                qemu_ids = sorted(i.id for i in idents if i.uid.hex() in QEMU_UIDS)
                host_ids = sorted(i.id for i in idents if i.uid.hex() not in QEMU_UIDS)
                ids = sorted(host_ids + qemu_ids)
                ok = len(host_ids) == 4 and len(qemu_ids) == len(qemus)
                bus.send(P.BROADCAST, P.WRITE, bytes([8, 0, 0]))  # CCW limit 0: speed mode
                bus.pause(0.1)
                bus.send(P.BROADCAST, P.WRITE, bytes([49, 1]))  # speed mode before homing
                bus.pause(0.1)
                # heartbeat off: else each servo stops itself 500 ms after its last packet
                # (§7.1), and the stop measured would be the heartbeat's, not the bus's
                bus.send(P.BROADCAST, P.WRITE, bytes([17, 0]))
                bus.pause(0.1)
                for start in ("SYNC WRITE", "REG WRITE + ACTION"):
                    _, n = host_switches(log.name, host_ids, 1, 0)
                    if start == "SYNC WRITE":
                        sent, frame_us = anchored(
                            bus, lambda: bus.sync_write("moving_speed", {i: 90 for i in ids}))
                    else:
                        for i in ids:
                            bus.reg_write(i, "moving_speed", 90)
                        sent, frame_us = anchored(bus, bus.action)
                    bus.pause(0.5)
                    began, n = host_switches(log.name, host_ids, 1, n)
                    stop_by = "REG WRITE + ACTION" if start == "SYNC WRITE" else "SYNC WRITE"
                    if stop_by == "SYNC WRITE":
                        bus.sync_write("moving_speed", {i: 0 for i in ids})
                    else:
                        for i in ids:
                            bus.reg_write(i, "moving_speed", 0)
                        bus.action()
                    polled = bracketed(bus, ids, 0, timeout=5.0)
                    bus.pause(0.2)
                    ended, _ = host_switches(log.name, host_ids, 0, n)
                    ok &= len(began) == len(ended) == len(host_ids) and len(polled) == len(ids)
                    if len(began) == len(host_ids):
                        skew = max(began.values()) - min(began.values())
                        ok &= skew <= TICK_US
                        print("bench ids: coordinated start skew %d us by %s (%d host nodes, "
                              "limit 1 tick = %d us)%s" % (skew, start, len(host_ids), TICK_US,
                                                          "" if skew <= TICK_US else "  !! OVER"))
                    if len(ended) == len(host_ids):
                        print("bench ids: end skew %d us, stopped by %s (%d host nodes, "
                              "virtual clock)" % (max(ended.values()) - min(ended.values()),
                                                  stop_by, len(host_ids)))
                    if len(polled) == len(ids) and len(began) == len(host_ids):
                        # every servo polled: the host nodes' exact stops check the anchor
                        c_hi = min(began.values()) - (sent * 1e6 + frame_us)
                        least, most, width, missed = all_ends(polled, c_hi, ended)
                        print("bench ids: end skew %s, stopped by %s (all %d servos, %d on "
                              "QEMU; each polled, placed on the virtual clock by the start "
                              "frame, within %d ms)%s" % (
                                  ms_range(least, most), stop_by, len(ids), len(qemu_ids),
                                  -(-width // 1000),
                                  "  !! host node(s) %s outside their polled bracket" % missed
                                  if missed else ""))
                ok &= trajectory(bus, log.name, host_ids, qemu_ids)
        finally:
            p.terminate()
            p.wait()
        if not ok:
            print("!! coordinated start: not every servo started and stopped (see above)")
    finally:
        for q in qemus:
            q.stop()
        log.close()
        os.unlink(log.name)


def main():
    build = sys.argv[1] if len(sys.argv) > 1 else "build/bench"
    sim = os.path.join(build, "servo-sim")
    if not os.access(sim, os.X_OK):
        sim = os.path.join("build", "host", "servo-sim")
    sizes = [int(x) for x in os.environ.get("IDS_BENCH_N", "10,50,253").split(",")]
    coordinated(sim)
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
