"""Issue 26: every entry point of the SDK raises only ServoBusError, whatever it is given
(the README promises it). Every public method of Bus is called with a wrong value in
each of its parameters in turn, the others being sensible, on a live servo-sim bus."""

import inspect
import math

import pytest

from servobus import VARIANTS, Bus, BusTimeout, RangeError, ServoBusError
from servobus import image as I
from servobus import protocol as P

ARM_ID = 1  # the servo-sim servo the sensible arguments address

# A sensible value for each parameter name: only the parameter under test is wrong.
SENSIBLE = {
    "servo_id": ARM_ID, "reg": "return_delay", "value": 16, "address": 5, "count": 1,
    "regs": ["return_delay"], "regs_values": {"return_delay": 16}, "position": 10,
    "speed": 10, "delta": 5, "what": "start", "points": [(10, 10)], "new_id": 9,
    "ins": P.PING, "params": b"", "nbytes": 7, "frame_bytes": 10, "baud": 9600,
    "values": {ARM_ID: 16}, "data": b"\x10", "frame": P.instruction(ARM_ID, P.PING),
    "sent": P.instruction(ARM_ID, P.PING), "shape": lambda pkt: True,
    "e": BusTimeout("no answer", ARM_ID), "finds": [],
    "expect": [ARM_ID], "uid": "ff" * 12, "k": 0, "prefix": 0,
    # for the foot, so that update() stops at the model check: nothing is installed
    "image": I.build(3000, 5, VARIANTS["foot"].model_number),
}
WRONG = ["x", "", None, -1, 1.5, math.nan, math.inf, [1], {}, True, 10 ** 9, b"\x00", 255]
# Durations: short ones where a method waits, and what is wrong for one (1.5 s is not).
DURATIONS = {"timeout": 0.1, "poll": 0.02, "restart_timeout": 0.1, "window": 0.1,
             "seconds": 0.01}
WRONG_SECONDS = ["x", "", -1, math.nan, math.inf, [1], {}, True, 10 ** 9, b"\x00"]
# Parameters for which a wrong value is harmless but slow, or means "yes": a flag.
FLAGS = {"on", "check", "check_free", "check_duplicate", "check_variant", "motion",
         "raise_faults", "all_bauds", "check_duplicates"}
# Methods that end the session under test.
SKIP = {"close"}


def entry_points(bus):
    for name, fn in inspect.getmembers(bus, inspect.ismethod):
        if not name.startswith("_") and name not in SKIP:
            yield name, fn, [p for p in inspect.signature(fn).parameters.values()
                             if p.kind == p.POSITIONAL_OR_KEYWORD]


def call(fn, params, wrong_name, wrong):
    kwargs = {}
    for p in params:
        if p.name == wrong_name:
            kwargs[p.name] = wrong
        elif p.default is p.empty:
            kwargs[p.name] = SENSIBLE[p.name]
        elif p.name in DURATIONS:
            kwargs[p.name] = DURATIONS[p.name]
    return fn(**kwargs)


@pytest.fixture(scope="module")
def arm_bus(tmp_path_factory):
    from conftest import Sim
    sim = Sim(("1:arm",))
    with Bus(sim.url, timeout=0.05) as bus:
        yield bus
    sim.stop()


def test_every_entry_point_raises_only_servobus_errors(arm_bus):
    checked = set()
    for name, fn, params in entry_points(arm_bus):
        for p in params:
            if p.name in FLAGS:
                continue
            for wrong in WRONG_SECONDS if p.name in DURATIONS else WRONG:
                try:
                    call(fn, params, p.name, wrong)
                except ServoBusError:
                    pass
                except Exception as e:  # noqa: BLE001 (what the test is about)
                    pytest.fail("%s(%s=%r) raised %s: %s" % (name, p.name, wrong,
                                                             type(e).__name__, e))
            checked.add(name)
    # premise: the walk reached the entry points the issue names, and the whole API
    assert {"in_update_mode", "status_return_level", "move_absolute", "trajectory_write",
            "sync_write", "write_many", "update", "listen", "duplicate"} <= checked
    assert len(checked) >= 45, sorted(checked)


@pytest.mark.parametrize("servo_id", [254, 255, -1, "x"])
def test_in_update_mode_refuses_what_is_not_one_servo(arm_bus, servo_id):
    with pytest.raises(RangeError):  # before: ValueError or TypeError
        arm_bus.in_update_mode(servo_id)


def test_status_return_level_of_the_broadcast_id_is_refused_not_2(arm_bus):
    with pytest.raises(RangeError, match="broadcast"):  # before: it returned 2
        arm_bus.status_return_level(254)
    assert arm_bus.status_return_level(ARM_ID) == 2


@pytest.mark.parametrize("port,kw", [
    (None, {}), ("", {}), (5, {}), ("tcp://127.0.0.1:1", {"baud": "x"}),
    ("tcp://127.0.0.1:1", {"baud": 1234}), ("tcp://127.0.0.1:1", {"timeout": "x"}),
    ("tcp://127.0.0.1:1", {"timeout": math.nan}), ("tcp://nope", {}),
    ("ftp://127.0.0.1:1", {})])
def test_a_bus_that_cannot_be_opened_says_so_as_a_servobus_error(port, kw):
    with pytest.raises(ServoBusError):
        Bus(port, **kw)
