"""Issue 20: servoctl and the SDK tell the truth and never strand a user. One test (or a
part of one) per finding, against servo-sim, through the CLI where the finding was a CLI
one; every lock-out is undone through servoctl alone."""

import os
import signal
import subprocess
import sys
import time

import pytest

from conftest import PYROOT, wait_until
from servobus import (VARIANTS, Bus, ImageError, ProtocolError, RangeError,
                      ServoBusError, ServoFault)
from servobus import image as I
from servobus import protocol as P
from test_cli import fails, ok, servoctl

FOOT = VARIANTS["foot"].model_number
APP_SLOT = 4 * 1024  # byte offset of the application slot in a --state-dir flash file


def one_line(err):
    """The failure's one line: the last line of stderr, the only one that starts with
    `servoctl: ` other than notes (an update prints the image and progress before it)."""
    lines = [x for x in err.splitlines() if x.startswith("servoctl: ") and
             not x.startswith("servoctl: note: ")]
    assert "Traceback" not in err and len(lines) == 1 and err.endswith(lines[0] + "\n"), err
    return lines[0]


# ---- every answer matched to its request ----------------------------------------------

def test_a_late_answer_is_never_taken_for_the_next_request(sim_factory):
    sim = sim_factory("1:foot")
    with Bus(sim.url) as bus:
        bus.write(1, {"cw_angle_limit": 0, "ccw_angle_limit": 300})
        bus.write(1, "return_delay", 200)  # 100 ms: longer than the time-out below
    with Bus(sim.url, timeout=0.05) as bus:
        # each READ's answer comes after the 0.05 s time-out; the SDK sees the servo
        # answer PING and asks once more with the time-out of the baud rate. Before, the
        # late answer to the first READ (CW = 0) was returned for the second.
        for _ in range(2):
            assert bus.read(1, "cw_angle_limit") == 0
            assert bus.read(1, "ccw_angle_limit") == 300
        assert not bus.present(1)  # its PING answer arrives late too...
        # ... and is not read as a READ answer with "ERR 0x01 over-temperature"
        assert bus.read(1, "return_delay") == 200 and not bus.faults
        bus.timeout = None
        assert bus.known_level(1) == 2  # slow is not silent
        bus.write(1, "return_delay", 16)


def test_answer_shapes():
    from servobus.link import answer_shape
    ping = P.StatusPacket(bytes.fromhex("d5 5d 01 03 01 00 05"))
    read1 = P.StatusPacket(bytes.fromhex("d5 5d 01 03 00 07 0b"))
    written = P.StatusPacket(bytes.fromhex("d5 5d 01 02 00 03"))
    refused = P.StatusPacket(bytes.fromhex("d5 5d 01 02 20 23"))
    assert answer_shape(P.PING)(ping) and not answer_shape(P.PING)(read1)
    assert answer_shape(P.READ, b"\x05\x01")(read1)
    assert not answer_shape(P.READ, b"\x06\x02")(ping)  # 1 byte for a 2-byte READ
    assert answer_shape(P.WRITE)(written) and not answer_shape(P.WRITE)(ping)
    assert answer_shape(P.READ, b"\x06\x02")(refused) and answer_shape(P.WRITE)(refused)


def test_a_short_timeout_does_not_skip_the_model_check(sim_factory, tmp_path):
    sim = sim_factory("1:arm")
    img = tmp_path / "foot.img"
    img.write_bytes(I.build(3000, 5, FOOT))
    err = fails(2, "--port", sim.url, "--timeout", "0.01", "update", str(img))
    assert "the servo is model 0x5203 (arm)" in one_line(err)


# ---- no command strands a user ----------------------------------------------------------

def test_latched_protection_comes_back_through_servoctl(sim_factory):
    sim = sim_factory("2:foot")
    port = ["--port", sim.url, "--id", "2"]
    err = fails(2, *port, "set", "temperature_limit", "-1")
    assert "ID 2 is at 25 C now" in one_line(err) and "--force" in err  # register 46 (issue 13)
    assert ok(*port, "get", "temperature_limit", "--raw").strip() == "80"
    ok(*port, "set", "temperature_limit", "-1", "--force")
    assert wait_until(lambda: "over-temperature" in ok(*port, "ping"), timeout=3)
    # before: every command failed on the fault bit of the model-number READ
    rc, out, err = servoctl(*port, "get", "temperature_limit")
    assert rc == 0 and "temperature_limit = -1" in out
    assert "set clear_unload 1" in err  # the way out, said once
    rc, out, err = servoctl(*port, "move", "10", "--speed", "10")
    assert rc == 1 and "clear_unload" in one_line(err)
    ok(*port, "set", "temperature_limit", "80")
    ok(*port, "set", "clear_unload", "1")  # retried while the servo still sees the cause
    assert "present, no errors" in ok(*port, "ping")
    assert "goal 10" in ok(*port, "move", "10", "--speed", "90")


def test_status_return_level_0_comes_back_through_servoctl(sim_factory, tmp_path):
    sim = sim_factory("2:foot")
    port = ["--port", sim.url, "--id", "2"]
    err = fails(2, *port, "set", "status_return_level", "0")
    assert "answer nothing but PING" in one_line(err) and "--force" in err
    ok(*port, "set", "status_return_level", "0", "--force")
    err = fails(1, *port, "dump")
    assert "answers PING but not READ" in one_line(err)
    assert "set status_return_level 2" in err
    # register 16 back: a WRITE without answer, then verified
    assert "status_return_level = 2: written" in ok(*port, "set", "status_return_level", "2")
    assert ok(*port, "get", "status_return_level", "--raw").strip() == "2"
    assert "ID 2: foot" in ok(*port, "dump")
    # level 1: writes are not answered, but read back
    ok(*port, "set", "status_return_level", "1")
    assert "acceleration = 21" in ok(*port, "set", "acceleration", "21")
    assert ok(*port, "get", "acceleration", "--raw").strip() == "21"
    assert "(not confirmed" in ok(*port, "set", "goal_position", "10")  # clamped: no check
    # update at level 0, with and without the host's checks
    img = tmp_path / "foot.img"
    img.write_bytes(I.build(3000, 6, FOOT))
    for extra in ([], ["--no-check"]):
        ok(*port, "set", "status_return_level", "0", "--force")
        rc, out, err = servoctl(*port, "update", str(img), *extra)
        assert rc == 0, err
        assert "updated in" in out and "answers PING" in out  # before: "does not answer PING"
    # reset at level 0: before, it reported failure although it reset
    assert "reset to factory values" in ok(*port, "reset", "--yes")
    assert ok("--port", sim.url, "get", "status_return_level", "id", "--raw").split() == \
        ["2", "1"]


def test_baud_the_cli_will_not_follow_needs_force(sim_factory):
    sim = sim_factory("2:foot")
    port = ["--port", sim.url, "--id", "2"]
    err = fails(2, *port, "set", "baud_rate", "4")
    assert "would then answer at 115200 baud only" in one_line(err)
    assert "--baud 115200" in err
    assert ok(*port, "get", "baud_rate", "--raw").strip() == "0"
    ok(*port, "set", "baud_rate", "2")  # 9600: what servoctl talks at


# ---- no silent ID collisions ------------------------------------------------------------

def test_generic_set_id_and_reset_refuse_a_taken_id(sim_factory):
    sim = sim_factory("1:arm", "3:foot", "7:wrist")
    port = ["--port", sim.url]
    err = fails(2, *port, "--id", "3", "set", "id", "7")
    assert "ID 7 is already taken" in one_line(err) and "--force" in err
    err = fails(2, *port, "--id", "3", "reset", "--yes")
    assert "reset would move ID 3 to ID 1: ID 1 is already taken" in one_line(err)
    assert "ID 3 is now ID 4" in ok(*port, "--id", "3", "set", "id", "4")
    assert "present" in ok(*port, "--id", "4", "ping")
    # an ID and a register that is not next to it: the register first, then the ID
    assert "ID 4 is now ID 5" in ok(*port, "--id", "4", "set", "acceleration", "20", "id", "5")
    assert ok(*port, "--id", "5", "get", "acceleration", "--raw").strip() == "20"


@pytest.mark.parametrize("delay", [16, 150])  # the same return delay: garbled; else two
def test_two_servos_on_one_id_are_seen(sim_factory, delay):
    sim = sim_factory("1:arm", "2:foot", "5:wrist")
    port = ["--port", sim.url]
    ok(*port, "--id", "2", "set", "return_delay", str(delay))
    err = fails(2, *port, "--id", "2", "set-id", "1")
    ok(*port, "--id", "2", "set-id", "1", "--force")  # now two servos answer at ID 1
    with Bus(sim.url) as bus:
        assert bus.duplicate(1) and not bus.duplicate(5)
    rc, out, err = servoctl(*port, "scan")
    assert rc == 1 and "two servos answer at ID 1" in err, (out, err)
    assert "5  wrist" in out
    err = fails(1, *port, "--id", "1", "set-id", "9")
    assert "two servos answer at ID 1" in one_line(err)
    err = fails(1, *port, "--id", "1", "ping")
    assert "two servos" in one_line(err)
    assert fails(1, *port, "--id", "9", "ping")  # neither moved


# ---- all-or-nothing set -----------------------------------------------------------------

def test_set_is_all_or_nothing(sim_factory):
    sim = sim_factory("2:foot", "1:arm")
    port = ["--port", sim.url, "--id", "2"]
    err = fails(2, *port, "set", "ccw_angle_limit", "100", "cw_angle_limit", "200")
    assert "cw_angle_limit 200 would be above ccw_angle_limit 100" in one_line(err)
    err = fails(2, *port, "set", "cw_angle_limit", "400")
    assert "ccw_angle_limit read from ID 2" in one_line(err)
    err = fails(2, *port, "set", "return_delay", "30", "heartbeat_enable", "0",
                "base_acceleration", "5")
    assert "does not exist on the foot" in one_line(err)
    assert ok(*port, "get", "return_delay", "heartbeat_enable", "ccw_angle_limit",
              "cw_angle_limit", "--raw").split() == ["16", "1", "360", "0"]
    # contiguous: one WRITE; not contiguous: checked first, then one WRITE per run
    out = ok(*port, "set", "cw_angle_limit", "10", "ccw_angle_limit", "300",
             "return_delay", "20", "acceleration", "40")
    assert out.count(": written") == 4
    assert ok(*port, "get", "cw_angle_limit", "ccw_angle_limit", "return_delay",
              "acceleration", "--raw").split() == ["10", "300", "20", "40"]


def test_write_many_undoes_earlier_runs_when_a_later_one_is_refused(sim_factory):
    sim = sim_factory("1:arm")
    with Bus(sim.url) as bus:
        runs = bus.plan_write(1, {"return_delay": 30, "goal_position": 10})
        assert [a for a, _ in runs] == [5, 30]
        with pytest.raises(ServoBusError):  # the arm is not homed: the goal is refused
            bus.write_many(1, {"return_delay": 30, "goal_position": 10})
        assert bus.read(1, "return_delay") == 16


# ---- output says what the servo did -----------------------------------------------------

def test_motion_commands_say_what_the_servo_does(sim_factory):
    sim = sim_factory("2:foot", "1:arm", "3:base")
    port = ["--port", sim.url, "--id", "2"]
    err = fails(2, *port, "move", "10")  # moving speed 0 after power-up
    assert "moving speed is 0" in one_line(err) and "--speed" in err
    err = fails(2, *port, "move", "10", "--speed", "0")
    assert "--speed 0 does not move" in one_line(err)
    out = ok(*port, "move", "9999deg", "--speed", "360deg/s")
    assert "goal 360 (360 deg) (asked 9999" in out and "clamped" in out
    assert ok(*port, "get", "goal_position", "--raw").strip() == "360"
    err = fails(2, *port, "speed", "60deg/s")
    assert "position mode" in one_line(err)
    assert "set cw_angle_limit 0 ccw_angle_limit 0" in err
    ok(*port, "set", "cw_angle_limit", "0", "ccw_angle_limit", "0")
    assert "moving_speed = 60" in ok(*port, "speed", "60deg/s")
    ok(*port, "stop")
    assert "moving_speed = 60" in ok("--port", sim.url, "--id", "3", "speed", "60deg/s")
    ok("--port", sim.url, "--id", "3", "stop")
    err = fails(2, *port, "home")
    assert "ID 2 is a foot: no photo switches" in one_line(err)
    err = fails(2, "--port", sim.url, "--id", "3", "home")
    assert "base: no photo switches" in err


def test_get_of_an_absent_or_write_only_register_is_an_error(shared_sim):
    port = ["--port", shared_sim.url]
    err = fails(2, *port, "--id", "1", "get", "present_position")
    assert "does not exist on the arm" in one_line(err)
    err = fails(2, *port, "--id", "2", "get", "base_acceleration")
    assert "does not exist on the foot" in one_line(err)
    err = fails(2, *port, "get", "clear_unload")
    assert "write-only" in one_line(err)
    assert "present_position = " in ok(*port, "--id", "7", "get", "present_position")


def _interrupt(args, until, env=None):
    e = dict(os.environ, PYTHONPATH=PYROOT)
    e.update(env or {})
    p = subprocess.Popen([sys.executable, "-m", "servobus", *args], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, env=e)
    buf = ""
    deadline = time.monotonic() + 20
    while until not in buf and time.monotonic() < deadline:
        buf += p.stderr.read(1) if until.startswith("[") else p.stdout.read(1)
    time.sleep(0.1)
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=20)
    return p.returncode, err


def test_ctrl_c_says_what_is_still_going_on(sim_factory, tmp_path):
    sim = sim_factory("2:foot")
    port = ["--port", sim.url, "--id", "2"]
    rc, err = _interrupt([*port, "move", "300", "--speed", "20deg/s", "--wait"], "goal")
    assert rc == 130 and "may still be moving" in one_line(err)
    assert "servoctl --id 2 stop" in err
    ok(*port, "stop")
    img = tmp_path / "foot.img"
    img.write_bytes(I.build(20000, 6, FOOT))
    rc, err = _interrupt([*port, "update", str(img)], "[####")
    last = err.splitlines()[-1]
    assert rc == 130 and "interrupted during the update (at the data block" in last, err
    assert "ends 10 s after the last frame" in last
    # the refusal during that session names it
    err = fails(1, *port, "set", "acceleration", "20")
    assert "an update session still open" in one_line(err)


# ---- no tracebacks, no hangs ------------------------------------------------------------

@pytest.mark.parametrize("value", ["nan", "inf", "1e308", "0", "-1", "x"])
def test_timeout_option_is_range_checked(value):
    err = fails(2, "--port", "tcp://127.0.0.1:1", "--timeout", value, "ping")
    assert "--timeout" in one_line(err) or "seconds" in err


def test_update_refuses_what_is_not_an_image_file(tmp_path):
    port = ["--port", "tcp://127.0.0.1:1"]
    err = fails(2, *port, "update", "/dev/zero")
    assert "not a regular file" in one_line(err)
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    start = time.monotonic()
    err = fails(2, *port, "update", str(fifo))  # before: it hung
    assert "not a regular file" in one_line(err) and time.monotonic() - start < 5
    big = tmp_path / "big.img"
    with open(big, "wb") as f:
        f.truncate(3 << 30)  # sparse: 3 GiB that are never read
    err = fails(2, *port, "update", str(big), "--no-check")
    assert "larger than any image" in one_line(err)
    empty = tmp_path / "empty.img"
    empty.write_bytes(b"")
    err = fails(2, *port, "update", str(empty), "--no-check")
    assert "empty" in one_line(err)


def test_the_sdk_raises_only_its_own_errors(bus):
    for call in (lambda: bus.ping(254), lambda: bus.read(254, "id"),
                 lambda: bus.present(254), lambda: bus.update(254, I.build(3000, 1, FOOT)),
                 lambda: bus.read(-1, "id"), lambda: bus.ping("1"),
                 lambda: bus.write_raw(1, 0, bytes(300)), lambda: bus.update(1, b""),
                 lambda: bus.update(1, I.build(3000, 1, FOOT), retries=-1)):
        with pytest.raises(ServoBusError):
            call()
    with pytest.raises(RangeError, match="broadcast"):
        bus.ping(254)
    assert issubclass(ImageError, ServoBusError) and issubclass(ImageError, ValueError)
    for bad in (float("nan"), 0, -1, float("inf")):
        with pytest.raises(RangeError):
            Bus("tcp://127.0.0.1:1", timeout=bad)
    assert issubclass(ProtocolError, ServoBusError) and issubclass(ServoFault, ServoBusError)


# ---- a servo in its bootloader's update mode --------------------------------------------

def test_update_mode_is_named_and_left_with_a_good_image(sim_factory, tmp_path):
    """A damaged application keeps servo-sim's bootloader in update mode: what a servo
    whose new image did not confirm itself within 3 starts looks like to the host."""
    state = tmp_path / "state"
    sim_factory("2:foot", state_dir=state).stop()
    flash = state / "servo-2-foot.flash"
    data = bytearray(flash.read_bytes())
    data[APP_SLOT + 5000] ^= 0xFF
    flash.write_bytes(data)
    sim = sim_factory("2:foot", state_dir=state)
    port = ["--port", sim.url, "--id", "2"]
    err = fails(1, *port, "ping")
    assert "answers the update handshake" in one_line(err)
    assert "update mode" in err and "servoctl --id 2 update FILE" in err
    rc, out, err = servoctl(*port, "scan")
    assert rc == 1 and "but ID 2 answers the update handshake" in one_line(err)
    img = tmp_path / "foot.img"
    img.write_bytes(I.build(3000, 6, FOOT))
    rc, out, err = servoctl(*port, "update", str(img))
    assert rc == 0 and "now runs firmware version 6" in out, err
    assert "answers the update handshake" in err and "update mode" in err
    assert "present, no errors" in ok(*port, "ping")
