"""Issue 27's coordinated trajectory, as a property (make bench prints the same figures on
a larger mixed bus, tools/bench_ids.py): host nodes on servo-sim share one virtual clock,
so one broadcast TRAJECTORY WRITE and one broadcast TRAJECTORY ACTION start the same
trajectory on every servo within one control tick, and each ends it within one tick of
the others. Read from servo-sim --report-moves (register 42's switches in virtual time).

Also the documented reason why two arm servos homing at once can fail (§7.1, §9): a
servo the host does not address for 500 ms stops on the heartbeat, and a stop aborts
homing; the servos it keeps addressing home."""

import re
import time

from servobus import Bus
from servobus import protocol as P

LINE = re.compile(r"servo-sim: ID (\d+) moving (\d) at (\d+) us$")
TICK_US = 1000  # include/motion.h MOTION_TICK_US
IDS = (1, 2, 3)
# From 0 up through 120 to 60 (a reversal) and back up to 90: about 2.5 s at these speeds.
POINTS = [(80, 150), (120, 150), (60, 150), (90, 60)]


def switches(sim):
    """Stop servo-sim: [(ID, moving, virtual us)] from its --report-moves lines."""
    sim.proc.send_signal(15)
    _, err = sim.proc.communicate(timeout=5)
    return [(int(m.group(1)), int(m.group(2)), int(m.group(3)))
            for m in map(LINE.match, err.splitlines()) if m]


def runs(got):
    """Each run after the power-on lines: ({ID: start us}, {ID: end us}), the start the
    first switch to 1, the end the first switch to 0 after it."""
    out, start, end = [], {}, {}
    for i, moving, t in got[len(IDS):]:
        if moving:
            start.setdefault(i, t)
        elif i in start:
            end.setdefault(i, t)
        if len(end) == len(IDS):
            out.append((start, end))
            start, end = {}, {}
    return out


def skew(at):
    return max(at.values()) - min(at.values())


def test_broadcast_trajectory_ends_on_every_host_node_within_one_tick(sim_factory):
    sim = sim_factory(*("%d:foot" % i for i in IDS), extra=("--report-moves",))
    with Bus(sim.url) as bus:
        bus.send(P.BROADCAST, P.WRITE, bytes([17, 0]))  # heartbeat off: the bus stays quiet
        bus.pause(0.1)
        bus.trajectory_write(P.BROADCAST, POINTS)
        bus.pause(0.1)
        bus.trajectory_action(P.BROADCAST)
        time.sleep(6.0)  # not a word to them while they run: nothing but the plan differs
        assert [bus.read(i, "moving") for i in IDS] == [0, 0, 0]
        # the same points started one ID after the other: the measure sees that skew
        for i in IDS:
            bus.trajectory_action(i)
        time.sleep(6.0)
        assert [bus.read(i, "moving") for i in IDS] == [0, 0, 0]
        assert [bus.read(i, "turned_angle") for i in IDS] == [90, 90, 90]
    (start, end), (start2, end2) = runs(switches(sim))
    assert set(start) == set(end) == set(IDS)
    assert min(end.values()) - max(start.values()) > 2000000  # the whole trajectory ran
    assert skew(start) <= TICK_US
    assert skew(end) <= TICK_US
    # addressed one by one: each ACTION waits for the previous answer (8 ms return delay)
    assert skew(start2) > 10 * TICK_US and skew(end2) > 10 * TICK_US


def test_two_arms_homing_at_once_the_one_not_addressed_stops_on_the_heartbeat(sim_factory):
    sim = sim_factory("1:arm", "2:arm", "3:arm", extra=("--report-moves",))
    with Bus(sim.url) as bus:
        bus.send(P.BROADCAST, P.WRITE, bytes([24, 1]))  # all three home, heartbeat on
        states, t_end = {}, time.monotonic() + 30.0
        while len(states) < 2 and time.monotonic() < t_end:
            for i in (1, 2):  # ID 3 is never addressed
                st = bus.read(i, "homing") >> 4
                if st in (2, 3):
                    states.setdefault(i, st)
            bus.pause(0.1)
        assert states == {1: 2, 2: 2}  # done
        assert bus.read(3, "homing") >> 4 == 3  # failed: aborted by the heartbeat
    got = switches(sim)
    began = {i: t for i, m, t in got[3:] if m == 1}
    stopped = {}
    for i, m, t in got[3:]:
        if m == 0:
            stopped.setdefault(i, t)
    assert began[1] == began[2] == began[3]
    # ID 3 stops 500 ms after the broadcast (plus its ramp down), the others home (~9 s)
    assert 500000 <= stopped[3] - began[3] < 1500000
    assert stopped[1] - began[1] > 5000000 and stopped[2] - began[2] > 5000000
