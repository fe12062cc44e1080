"""The SDK's commit budget estimate (servobus/budget.py) against the servo's own count
(issue 25): servo-sim --report-commits prints each servo's flash commit tokens as the
store spends and refills them. Every frame that spends a commit is driven through the
SDK (WRITE, SYNC WRITE, REG WRITE + ACTION addressed and broadcast, START/END, a
completed homing, RESET), and frames that spend none (RAM registers, a START that
changes no limit, a held RAM write), and after each the estimate equals the count."""

import re
import threading

from conftest import wait_until

from servobus import Bus

LINE = re.compile(r"servo-sim: ID (\d+) commit tokens (\d+)")


class Tokens:
    """The latest token count servo-sim reported for each ID (read as it runs)."""

    def __init__(self, proc):
        self.by_id = {}
        self._thread = threading.Thread(target=self._read, args=(proc.stderr,), daemon=True)
        self._thread.start()

    def _read(self, stream):
        for line in iter(stream.readline, ""):
            m = LINE.search(line)
            if m:
                self.by_id[int(m.group(1))] = int(m.group(2))


def check(bus, tokens, expected):
    """Each ID's estimate equals the servo's count, and both are what the step spent."""
    def agree():
        return all(tokens.by_id.get(i) == bus.commit_budget.tokens(bus.budget_key(i)) == n
                   for i, n in expected.items())
    assert wait_until(agree, timeout=2.0), (
        "servo %s, SDK %s, expected %s" % (
            {i: tokens.by_id.get(i) for i in expected},
            {i: bus.commit_budget.tokens(bus.budget_key(i)) for i in expected}, expected))


def test_the_sdk_counts_every_commit_the_servo_spends(sim_factory, tmp_path):
    # The first start gives the foot its ID 2 (a commit); after a power cycle both
    # buckets are full, as the SDK assumes for a servo it has not seen.
    assert sim_factory("1:arm", "2:foot", state_dir=tmp_path).stop() == 0
    sim = sim_factory("1:arm", "2:foot", state_dir=tmp_path, extra=("--report-commits",))
    tokens = Tokens(sim.proc)
    with Bus(sim.url) as bus:
        check(bus, tokens, {1: 64, 2: 64})
        bus.write(2, "temperature_limit", 70)                 # WRITE to EEPROM
        check(bus, tokens, {1: 64, 2: 63})
        bus.write(2, "acceleration", 20)                      # RAM: nothing to commit
        check(bus, tokens, {1: 64, 2: 63})
        bus.sync_write("temperature_limit", {1: 71, 2: 72})   # SYNC WRITE: one each
        check(bus, tokens, {1: 63, 2: 62})
        bus.reg_write(1, "cw_angle_limit", 10)                # held: nothing yet
        check(bus, tokens, {1: 63, 2: 62})
        bus.action(1)                                         # ACTION commits it
        check(bus, tokens, {1: 62, 2: 62})
        bus.reg_write(2, "temperature_limit", 73)
        bus.reg_write(1, "acceleration", 30)                  # a RAM write held
        bus.action()                                          # broadcast ACTION
        check(bus, tokens, {1: 62, 2: 61})
        bus.write(2, "cw_angle_limit", 10)
        check(bus, tokens, {1: 62, 2: 60})
        bus.start_end(2, "start")                             # CW 10 -> 0: a commit
        check(bus, tokens, {1: 62, 2: 59})
        bus.start_end(2, "start")                             # CW stays 0: none
        check(bus, tokens, {1: 62, 2: 59})
        bus.write(2, {"goal_position": 100, "moving_speed": 200})
        assert wait_until(lambda: not bus.read(2, "moving"), timeout=5.0)
        bus.start_end(2, "end")                               # CCW to here: a commit
        check(bus, tokens, {1: 62, 2: 58})
        bus.home(1)                                           # homing sets the limits
        bus.wait_homed(1, timeout=30.0)
        check(bus, tokens, {1: 61, 2: 58})
        bus.reset(1)                                          # RESET: factory values
        check(bus, tokens, {1: 60, 2: 58})
