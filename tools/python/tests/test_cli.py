"""servoctl (python3 -m servobus) end to end against servo-sim."""

import os
import shutil
import subprocess
import sys

from conftest import BUS_IDS, PYROOT


def servoctl(*args, python=sys.executable, env=None):
    e = dict(os.environ, PYTHONPATH=PYROOT)
    e.pop("SERVOBUS_PORT", None)
    e.update(env or {})
    p = subprocess.run([python, "-m", "servobus", *args], capture_output=True, text=True,
                       env=e, timeout=30)
    return p.returncode, p.stdout, p.stderr


def ok(*args, **kw):
    rc, out, err = servoctl(*args, **kw)
    assert rc == 0, (args, rc, out, err)
    return out


def fails(rc_expected, *args, **kw):
    rc, out, err = servoctl(*args, **kw)
    assert rc == rc_expected, (args, rc, out, err)
    return err


def test_scan(shared_sim):
    out = ok("--port", shared_sim.url, "scan", "--all-bauds")
    assert "5 servos found" in out
    rows = [line.split() for line in out.splitlines()[2:]]
    assert [int(r[0]) for r in rows] == BUS_IDS
    assert [r[1] for r in rows] == ["arm", "foot", "base", "wrist", "finger"]


def test_ping_and_time_out(shared_sim):
    assert "ID 7: present, no errors" in ok("ping", "--id", "7", "--port", shared_sim.url)
    err = fails(1, "--port", shared_sim.url, "--id", "9", "ping")
    assert "servoctl: no status packet from ID 9 at 9600 baud" in err
    assert "try `servoctl scan --all-bauds`" in err


def test_port_from_environment(shared_sim):
    assert "ID 1: present" in ok("ping", env={"SERVOBUS_PORT": shared_sim.url})


def test_get_set_with_ranges(shared_sim):
    port = ["--port", shared_sim.url, "--id", "2"]
    assert "acceleration = 36 (360 deg/s^2)" in ok(*port, "get", "acceleration")
    assert "return_delay = 10 (5 ms): written" in ok(*port, "set", "return_delay", "5ms")
    assert ok(*port, "get", "return_delay", "--raw").strip() == "10"
    ok(*port, "set", "5", "16")  # by address
    err = fails(2, *port, "set", "return_delay", "256")
    assert "return_delay: 256 is out of range 0..255" in err
    err = fails(2, *port, "set", "base_acceleration", "1")
    assert "does not exist on the foot" in err
    err = fails(2, *port, "set", "acceleration")
    assert "has no value" in err
    assert ok(*port, "get", "return_delay", "--raw").strip() == "16"


def test_negative_values(shared_sim):
    port = ["--port", shared_sim.url, "--id", "3"]
    assert "moving_speed = -45 (-45 deg/s)" in ok(*port, "speed", "-45deg/s")
    assert ok(*port, "get", "moving_speed", "--raw").strip() == "-45"
    assert "moving_speed = 0 (stop)" in ok(*port, "stop")
    assert "heartbeat" not in servoctl(*port, "stop")[2]


def test_dump_names_every_register(shared_sim):
    out = ok("--port", shared_sim.url, "--id", "1", "dump")
    assert out.startswith("ID 1: arm (model 0x5203), firmware")
    from servobus import REGISTERS
    for name in REGISTERS:
        assert name in out
    assert "(not on this variant)" in out and "30 (3 A)" in out


def test_set_id_refuses_a_taken_id(shared_sim):
    err = fails(2, "--port", shared_sim.url, "--id", "1", "set-id", "7")
    assert "ID 7 is already taken on the bus" in err
    assert "ID 200 is now ID 201" in ok("--port", shared_sim.url, "--id", "200", "set-id", "201")
    ok("--port", shared_sim.url, "--id", "201", "set-id", "200")


def test_traj_and_move(shared_sim):
    port = ["--port", shared_sim.url, "--id", "2"]
    assert "2 trajectory points stored" in ok(*port, "traj", "10:90", "0:90", "--no-run")
    err = fails(2, *port, "traj", "10:0")
    assert "speed 0" in err
    assert "goal 0 (0 deg), speed 90 (90 deg/s)" in ok(*port, "move", "0", "--speed", "90")
    out = ok(*port, "traj", "20:360", "0:360", "--wait")
    assert "trajectory started" in out and "trajectory done at" in out
    rc, out, err = servoctl(*port, "move", "10")
    assert rc == 0 and "heartbeat on (register 17)" in err


def test_home_writes_register_24(shared_sim):
    port = ["--port", shared_sim.url, "--id", "7"]
    assert "homing started" in ok(*port, "home")
    assert ok(*port, "get", "homing", "--raw").strip() in ("1", "17", "33", "49")
    ok(*port, "set", "homing", "0")


def test_monitor_with_plot(shared_sim, tmp_path):
    png = tmp_path / "m.png"
    out = ok("--port", shared_sim.url, "--id", "7", "monitor", "--count", "3",
             "--interval", "0.02", "--plot", str(png))
    lines = [line for line in out.splitlines() if " s  position " in line]
    assert len(lines) == 3 and "temperature" in lines[0] and "errors: none" in lines[0]
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_monitor_plot_without_matplotlib(shared_sim, tmp_path):
    code = ("import sys; sys.modules['matplotlib'] = None; from servobus.cli import main; "
            "sys.exit(main(sys.argv[1:]))")
    p = subprocess.run([sys.executable, "-c", code, "--port", shared_sim.url, "monitor",
                        "--count", "1", "--plot", str(tmp_path / "x.png")],
                       capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=PYROOT))
    assert p.returncode == 1
    assert "--plot needs matplotlib: apt-get install python3-matplotlib" in p.stderr


def test_reset_needs_yes(sim_factory):
    sim = sim_factory("4:finger")
    err = fails(2, "--port", sim.url, "--id", "4", "reset")
    assert "add --yes" in err
    assert "reset to factory values" in ok("--port", sim.url, "--id", "4", "reset", "--yes")


def test_usage_errors():
    assert "no bus given" in fails(2, "ping")
    fails(2, "--port", "tcp://127.0.0.1:1", "frobnicate")
    assert "not one of" in fails(2, "--baud", "1234", "ping")
    assert "out of range 0-253" in fails(2, "--id", "254", "ping")


def test_connection_refused_says_start_servo_sim():
    from conftest import free_port
    err = fails(1, "--port", "tcp://127.0.0.1:%d" % free_port(), "ping")
    assert "is servo-sim running?" in err


def test_every_python3(shared_sim):
    """The CLI runs under /usr/bin/python3 and under the python3 first on PATH."""
    pythons = {os.path.realpath(p) for p in ("/usr/bin/python3", shutil.which("python3"))
               if p and os.path.exists(p)}
    for py in sorted(pythons):
        assert "ID 1: present" in ok("--port", shared_sim.url, "ping", python=py), py


def test_serial_port_errors_are_clear():
    err = fails(1, "--port", "/dev/does-not-exist", "ping")
    assert "cannot open /dev/does-not-exist" in err or "need pyserial" in err
