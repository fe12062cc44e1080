"""Issue 19, the SDK's part: the host's estimate of a servo's flash commit budget
(servobus/budget.py, docs/persistence.md "For host tools") and servoctl's warning."""

import json
import re
import signal
import time

from servobus import Bus
from servobus.budget import BURST, REFILL_S, CommitBudget
from test_cli import servoctl


class Clock:
    def __init__(self):
        self.t = 1000.0

    def __call__(self):
        return self.t


def test_the_estimate_replays_the_firmwares_token_bucket():
    clock = Clock()
    b = CommitBudget(clock=clock)
    assert b.tokens("s") == BURST  # full at power-up
    assert [b.commit("s") for _ in range(BURST)] == [0.0] * BURST  # the burst: at once
    assert b.commit("s") == REFILL_S  # the 65th waits a whole refill
    clock.t += 10
    assert b.commit("s") == REFILL_S - 10  # it shares the deferred commit
    clock.t += REFILL_S - 10  # the token arrives and goes to the deferred commit
    assert b.tokens("s") == 0
    clock.t += REFILL_S
    assert b.tokens("s") == 1 and b.commit("s") == 0.0
    clock.t += BURST * REFILL_S  # long enough: full again, and time spent full is lost
    assert b.tokens("s") == BURST
    b.commit("s")
    clock.t += REFILL_S - 1
    assert b.tokens("s") == BURST - 1  # the refill clock started at that commit
    clock.t += 1
    assert b.tokens("s") == BURST
    assert b.tokens("other") == BURST  # per servo


def test_restart_and_id_change(tmp_path):
    clock = Clock()
    path = tmp_path / "state.json"
    b = CommitBudget(str(path), clock=clock)
    for _ in range(BURST):
        b.commit("p#1")
    b.moved("p#1", "p#5")
    assert b.tokens("p#5") == 0 and b.tokens("p#1") == BURST
    assert CommitBudget(str(path), clock=clock).tokens("p#5") == 0  # kept between runs
    b.restarted("p#5")
    assert CommitBudget(str(path), clock=clock).tokens("p#5") == BURST
    path.write_text("garbage")
    assert CommitBudget(str(path), clock=clock).tokens("p#5") == BURST  # never fatal


def test_servoctl_warns_when_a_write_is_past_the_budget(sim_factory, tmp_path):
    state = tmp_path / "state"
    sim = sim_factory("2:foot", state_dir=state)
    budget = tmp_path / "budget.json"
    env = {"SERVOBUS_STATE": str(budget)}
    # this host made 64 EEPROM commits to ID 2 just now (a commissioning script)
    with Bus(sim.url) as bus:
        bus.commit_budget = CommitBudget(str(budget))
        for i in range(BURST):
            bus.write(2, "return_delay", 20 + i % 2)  # each one a change: a commit
            assert bus.commit_wait == 0.0
    rc, out, err = servoctl("--port", sim.url, "--id", "2", "set", "return_delay", "30",
                            env=env)
    assert rc == 0 and "return_delay = 30" in out
    assert re.search(r"in force now but reaches flash in up to 6\d s", err), err
    assert "do not cut the power before" in err
    # a RAM register is not a commit: no warning
    rc, out, err = servoctl("--port", sim.url, "--id", "2", "set", "acceleration", "30",
                            env=env)
    assert rc == 0 and "flash" not in err
    # a value already there is not a commit either
    rc, out, err = servoctl("--port", sim.url, "--id", "2", "set", "return_delay", "30",
                            env=env)
    assert rc == 0 and "flash" not in err
    # the warning is true: a power cut now loses the value the servo answered for
    sim.stop(signal.SIGKILL)
    sim = sim_factory("2:foot", state_dir=state)
    with Bus(sim.url) as bus:
        assert bus.read(2, "return_delay") in (20, 21)  # the last committed value
    assert json.loads(budget.read_text())  # the estimate is kept per servo


def test_no_warning_within_the_budget(sim_factory, tmp_path):
    sim = sim_factory("2:foot")
    env = {"SERVOBUS_STATE": str(tmp_path / "b.json")}
    start = time.monotonic()
    rc, out, err = servoctl("--port", sim.url, "--id", "2", "set", "return_delay", "30",
                            env=env)
    assert rc == 0 and "flash" not in err and time.monotonic() - start < 10
