"""servo-sim --report-moves prints each switch of a servo's register 42 (moving) as
`servo-sim: ID N moving 0|1 at T us`, T its virtual clock: make bench's coordinated-start
skew (tools/bench_ids.py) is read from these lines. One broadcast ACTION starts every held
REG WRITE in the same main-loop pass, so the servos' lines carry one time."""

import re
import time

from servobus import Bus
from servobus import protocol as P

LINE = re.compile(r"servo-sim: ID (\d+) moving (\d) at (\d+) us$")


def moves(sim):
    sim.proc.send_signal(15)
    _, err = sim.proc.communicate(timeout=5)
    return [(int(m.group(1)), int(m.group(2)), int(m.group(3)))
            for m in map(LINE.match, err.splitlines()) if m]


def test_action_starts_every_held_write_at_one_time_and_each_stop_is_reported(sim_factory):
    sim = sim_factory("1:arm", "2:arm", "3:foot", extra=("--report-moves",))
    with Bus(sim.url) as bus:
        bus.send(P.BROADCAST, P.WRITE, bytes([8, 0, 0]))  # CCW limit 0: speed mode
        bus.pause(0.1)
        bus.send(P.BROADCAST, P.WRITE, bytes([49, 1]))    # speed mode before homing
        bus.pause(0.1)
        for i in (1, 2):                                  # 3 holds nothing: stays still
            bus.reg_write(i, "moving_speed", 90)
        time.sleep(0.2)
        assert [bus.read(i, "moving") for i in (1, 2, 3)] == [0, 0, 0]
        bus.action()
        time.sleep(0.3)
        bus.sync_write("moving_speed", {1: 0, 2: 0})
        time.sleep(0.5)
    got = moves(sim)
    assert [(i, m) for i, m, _ in got[:3]] == [(1, 0), (2, 0), (3, 0)]  # once at the start
    starts = {i: t for i, m, t in got[3:] if m == 1}
    stops = {i: t for i, m, t in got[3:] if m == 0}
    assert set(starts) == set(stops) == {1, 2}
    assert starts[1] == starts[2]
    assert all(stops[i] - starts[i] >= 250000 for i in (1, 2))  # ran until the stop
