"""Issue 20: servoctl under random argv (Hypothesis): any command, any options, on a live
servo-sim bus whose state the earlier examples keep changing. Every run ends with exit
status 0, 1 or 2 within its time-out; a failure (1, 2) is one line on stderr (after the
notes and the progress an update prints); never a traceback.

Bounded for `make test` (SERVOBUS_ARGV_EXAMPLES, default 30). Two adjustments keep each
run bounded without hiding anything: `monitor` without --count/--duration runs until
Ctrl-C, so it gets --count 2; --wait without --wait-timeout waits up to 30-60 s by
design, so it gets --wait-timeout 2."""

import os
import subprocess
import sys

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import PYROOT, Sim
from servobus import VARIANTS
from servobus import image as I

EXAMPLES = int(os.environ.get("SERVOBUS_ARGV_EXAMPLES", "30"))
RUN_TIMEOUT_S = 25.0  # per servoctl run: the longest legitimate one is far shorter

COMMANDS = ["scan", "ping", "get", "set", "dump", "move", "speed", "stop", "home", "traj",
            "set-id", "monitor", "update", "reset", "frobnicate", "--help"]
REGISTERS = ["id", "baud_rate", "return_delay", "cw_angle_limit", "ccw_angle_limit",
             "temperature_limit", "status_return_level", "heartbeat_enable",
             "goal_position", "moving_speed", "acceleration", "clear_unload", "homing",
             "present_position", "base_acceleration", "model_number", "16", "10", "99",
             "nope"]
VALUES = ["0", "1", "2", "-1", "90deg", "-45deg/s", "360", "9999deg", "1e999deg", "nan",
          "inf", "0x20", "abc", "", "65536", "8ms", "60C", "-0", "3.5", "10:90", "0:0",
          "1" * 50, "9" * 400 + "deg"]
NUMBERS = ["0", "-1", "0.5", "1", "2", "nan", "inf", "1e308", "x", "", "3"]
IDS = ["1", "2", "3", "7", "0", "253", "254", "-1", "x", "0x02"]


@pytest.fixture(scope="module")
def argv_sim(tmp_path_factory):
    d = tmp_path_factory.mktemp("argv")
    good = d / "foot.img"
    good.write_bytes(I.build(3000, 9, VARIANTS["foot"].model_number))
    bad = d / "bad.img"
    bad.write_bytes(good.read_bytes()[:2000])
    empty = d / "empty.img"
    empty.write_bytes(b"")
    fifo = d / "fifo"
    os.mkfifo(fifo)
    files = [str(good), str(bad), str(empty), str(fifo), "/dev/zero", str(d / "none"),
             str(d)]
    sim = Sim(("1:arm", "2:foot", "3:base", "7:wrist"))
    yield sim, files, str(d / "plot.png")
    sim.stop()


def argv_strategy(files, plot):
    option = st.one_of(
        st.tuples(st.just("--id"), st.sampled_from(IDS)),
        st.tuples(st.just("--timeout"), st.sampled_from(NUMBERS)),
        st.tuples(st.just("--baud"), st.sampled_from(["9600", "115200", "1792000", "1234",
                                                      "x"])),
        st.tuples(st.sampled_from(["--wait", "--force", "--yes", "--raw", "--all-bauds",
                                   "--no-check", "--no-run", "--bogus"])),
        st.tuples(st.just("--speed"), st.sampled_from(VALUES)),
        st.tuples(st.sampled_from(["--wait-timeout", "--interval", "--duration"]),
                  st.sampled_from(NUMBERS)),
        st.tuples(st.sampled_from(["--count", "--retries", "--point-size"]),
                  st.sampled_from(NUMBERS + ["3", "4", "101"])),
        st.tuples(st.just("--plot"), st.sampled_from([plot, "/nonexistent/x.png"])),
    )
    positional = st.one_of(st.sampled_from(REGISTERS), st.sampled_from(VALUES),
                           st.sampled_from(files), st.sampled_from(IDS))
    return st.tuples(st.sampled_from(COMMANDS), st.lists(positional, max_size=4),
                     st.lists(option, max_size=4))


def _bounded(argv):
    """The two adjustments of the module docstring."""
    if argv[0] == "monitor" and "--count" not in argv and "--duration" not in argv:
        argv += ["--count", "2"]
    if "--wait" in argv and "--wait-timeout" not in argv:
        argv += ["--wait-timeout", "2"]
    return argv


def test_servoctl_under_random_argv(argv_sim):
    sim, files, plot = argv_sim
    env = dict(os.environ, PYTHONPATH=PYROOT, SERVOBUS_PORT=sim.url)

    @settings(max_examples=EXAMPLES, deadline=None, derandomize=False,
              suppress_health_check=list(HealthCheck))
    @given(argv_strategy(files, plot))
    def run(drawn):
        command, positionals, options = drawn
        argv = _bounded([command] + positionals + [x for o in options for x in o])
        try:
            p = subprocess.run([sys.executable, "-m", "servobus", *argv], env=env,
                               capture_output=True, text=True, timeout=RUN_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            pytest.fail("servoctl %s: still running after %.0f s" % (argv, RUN_TIMEOUT_S))
        assert p.returncode in (0, 1, 2), (argv, p.returncode, p.stderr)
        assert "Traceback" not in p.stderr, (argv, p.stderr)
        if p.returncode:
            lines = [x for x in p.stderr.splitlines() if x.startswith("servoctl: ") and
                     not x.startswith("servoctl: note: ")]
            assert len(lines) == 1 and p.stderr.endswith(lines[0] + "\n"), (argv, p.stderr)

    run()
