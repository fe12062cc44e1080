"""Issue 26, servoctl and the SDK: one test (or part of one) per finding, against
servo-sim; what went on the wire is read from a tap in front of servo-sim (wire.py), not
from the SDK's own account."""

import time

import pytest

from conftest import wait_until
from servobus import Bus, DuplicateId
from servobus import protocol as P
from servobus.protection import CLEAR_WINDOW_S, SAFETY_DRAIN_S
from servobus.registers import REGISTERS
from test_cli import fails, ok, servoctl
from test_image import APP_SLOT, c_defines
from test_truth import one_line
from wire import WireTap

TEMPERATURE_LIMIT = REGISTERS["temperature_limit"].address
CLEAR_UNLOAD = REGISTERS["clear_unload"].address


def writes(tap, mark, address):
    """The data of every WRITE to address that reached servo-sim since mark."""
    return [raw[6:-1] for _, raw in tap.packets(mark)
            if raw[4] == P.WRITE and raw[5] == address]


def latch_over_temperature(port):
    """A foot at 25 C with its temperature limit at -1 C: an unload, latched."""
    ok(*port, "set", "temperature_limit", "-1", "--force")
    assert wait_until(lambda: "over-temperature" in ok(*port, "ping"), timeout=3)


# ---- clearing an unload ---------------------------------------------------------------

def test_the_clear_retry_window_comes_from_the_firmware_drain_time():
    c = c_defines("include/motion.h", "src/safety.c")
    drain = max(c["TEMP_TRIP"], c["ACC_TRIP"]) * c["MOTION_TICK_US"] / 1e6
    assert SAFETY_DRAIN_S == drain == 2.0
    assert CLEAR_WINDOW_S >= 2 * drain  # margin for a late host or simulator


def test_set_limit_and_clear_in_one_command_retries_only_the_clear(sim_factory):
    sim = sim_factory("2:foot")
    tap = WireTap(sim.port)
    try:
        port = ["--port", tap.url, "--id", "2"]
        latch_over_temperature(port)
        mark = tap.mark()
        out = ok(*port, "set", "temperature_limit", "80", "clear_unload", "1")
        assert "clear_unload = 1 (after 2." in out and "still saw the cause" in out
        # before: each retry wrote 80, had the clear refused, and wrote -1 back
        limits = writes(tap, mark, TEMPERATURE_LIMIT)
        assert limits == [bytes([80])], limits
        assert writes(tap, mark, CLEAR_UNLOAD)  # the clear, tried until taken
        assert "present, no errors" in ok(*port, "ping")
    finally:
        tap.close()


def test_a_clear_right_after_the_cause_is_removed_works_every_time(sim_factory):
    sim = sim_factory("2:foot")
    port = ["--port", sim.url, "--id", "2"]
    latch_over_temperature(port)
    with Bus(sim.url, raise_faults=False) as bus:
        bus.write(2, "temperature_limit", 80)
        start = time.monotonic()
        bus.write_many(2, {"clear_unload": 1})  # before: refused at once
        took = time.monotonic() - start
        assert bus.ping(2) & P.ERR_FAULTS == 0
    # the servo saw the cause for about its drain time, and the window covers it
    assert SAFETY_DRAIN_S - 0.6 <= took <= CLEAR_WINDOW_S, took
    latch_over_temperature(port)
    ok(*port, "set", "temperature_limit", "80")
    assert "clear_unload = 1 (after" in ok(*port, "set", "clear_unload", "1")


def test_a_clear_refused_for_good_says_the_cause_is_still_there(sim_factory):
    sim = sim_factory("2:foot")
    port = ["--port", sim.url, "--id", "2"]
    latch_over_temperature(port)
    start = time.monotonic()
    err = fails(1, *port, "set", "clear_unload", "1")
    assert CLEAR_WINDOW_S <= time.monotonic() - start < CLEAR_WINDOW_S + 5
    assert "over-temperature" in one_line(err) and "is still there" in err


# ---- two servos at one ID -------------------------------------------------------------

@pytest.mark.parametrize("delay", [16, 150])  # the same return delay: garbled; else two
def test_get_and_dump_refuse_two_servos_at_one_id(sim_factory, delay):
    sim = sim_factory("1:arm", "2:foot")
    port = ["--port", sim.url]
    ok(*port, "--id", "2", "set", "return_delay", str(delay))
    ok(*port, "--id", "2", "set-id", "1", "--force")  # now an arm and a foot at ID 1
    # before: exit 0, with values mixed from both servos
    err = fails(1, *port, "--id", "1", "get", "model_number", "return_delay")
    assert "two servos answer at ID 1" in one_line(err)
    err = fails(1, *port, "--id", "1", "dump")
    assert "two servos answer at ID 1" in one_line(err)
    with Bus(sim.url) as bus:
        with pytest.raises(DuplicateId):
            bus.dump(1)


# ---- reset on proof only ----------------------------------------------------------------

def test_reset_of_an_absent_id_fails_and_resets_nothing(sim_factory):
    sim = sim_factory("1:arm", "2:foot")
    port = ["--port", sim.url]
    ok(*port, "--id", "1", "set", "return_delay", "30")
    # before: exit 0, "it now answers at ID 1", because the arm answers there
    err = fails(1, *port, "--id", "9", "reset", "--yes", "--force")
    assert "nothing was reset" in one_line(err) and "ID 9" in err
    assert ok(*port, "--id", "1", "get", "return_delay", "--raw").strip() == "30"
    assert "ID 2: present" in ok(*port, "--id", "2", "ping")  # the foot is where it was


def test_reset_of_a_servo_in_update_mode_fails_and_names_it(sim_factory, tmp_path):
    state = tmp_path / "state"
    sim_factory("1:arm", "2:foot", state_dir=state).stop()
    flash = state / "servo-2-foot.flash"
    data = bytearray(flash.read_bytes())
    data[APP_SLOT + 5000] ^= 0xFF  # a damaged application: the bootloader stays in charge
    flash.write_bytes(data)
    sim = sim_factory("1:arm", "2:foot", state_dir=state)
    port = ["--port", sim.url, "--id", "2"]
    err = fails(1, *port, "reset", "--yes", "--force")
    assert "nothing was reset" in one_line(err) and "update mode" in err
    # update mode is named wherever it is the cause (before: "wrong ID or baud?")
    for args in (["get", "return_delay"], ["set", "acceleration", "20"],
                 ["move", "10", "--speed", "10"], ["dump"]):
        err = fails(1, *port, *args)
        assert "update mode" in one_line(err) and "update FILE" in err, args


# ---- every baud the port reaches --------------------------------------------------------

def test_id_checks_and_all_bauds_scan_see_a_servo_at_another_baud(sim_factory):
    sim = sim_factory("2:foot", "3:base")  # the foot at 9600 baud, the base at 115200
    port = ["--port", "rfc2217://127.0.0.1:%d" % sim.port]
    # before: allowed, and the foot joined the base at ID 3
    err = fails(2, *port, "--id", "2", "set-id", "3")
    assert "ID 3 is already taken" in one_line(err) and "at 115200 baud" in err
    ok(*port, "--id", "2", "set-id", "3", "--force")  # made on purpose now
    rc, out, err = servoctl(*port, "scan", "--all-bauds")
    # before: the base was hidden behind the foot, exit 0
    rows = [line.split() for line in out.splitlines()[2:]]
    assert [r[:3] for r in rows] == [["3", "foot", "9600"], ["3", "base", "115200"]], out
    assert rc == 1 and "two servos answer at ID 3" in one_line(err)
