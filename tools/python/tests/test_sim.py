"""servo-sim's command-line contract: arguments, errors, signals, --state-dir."""

import os
import signal
import socket

import pytest

from conftest import SIM, free_port, run_sim
from servobus import Bus, BusTimeout, ServoBusError


def assert_usage_error(args, *words):
    rc, out, err = run_sim(*args)
    assert rc == 2, (args, rc, err)
    assert err.startswith("servo-sim: ") and err.count("\n") == 1, err
    for w in words:
        assert w in err, (w, err)
    return err


@pytest.mark.parametrize("args,words", [
    (["--servo", "1:elbow"], ["bad variant 'elbow'", "base, foot, arm, wrist or finger"]),
    (["--servo", "254:arm"], ["bad ID '254'", "0-253"]),
    (["--servo", "x:arm"], ["bad ID 'x'"]),
    (["--servo", "arm"], ["expected ID:VARIANT"]),
    (["--servo", "3:arm:0102030405060708090a0b0c", "--servo", "4:foot:0102030405060708090a0b0c"],
     ["duplicate UID", "3:arm", "4:foot"]),
    (["--servo", "3:arm:01020304"], ["bad UID '01020304'", "24 hex digits"]),
    (["--servo", "3:arm:0102030405060708090a0bzz"], ["bad UID"]),
    (["--bogus"], ["unknown option '--bogus'", "usage"]),
    (["--servo"], ["--servo needs a value"]),
])
def test_bad_arguments_exit_2(args, words):
    assert_usage_error(["--listen", "127.0.0.1:%d" % free_port(), *args], *words)


@pytest.mark.parametrize("listen", ["nonsense", "127.0.0.1", "127.0.0.1:99999",
                                    "127.0.0.1:-1", "1.2.3:80", ":80", "host.example:80"])
def test_bad_listen_exit_2(listen):
    assert_usage_error(["--listen", listen], "--listen")


def test_missing_listen_exit_2():
    assert_usage_error([], "missing --listen")


def test_port_in_use_exit_2(sim_factory):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        port = s.getsockname()[1]
        assert_usage_error(["--listen", "127.0.0.1:%d" % port], "port in use", str(port))
    sim = sim_factory()
    assert_usage_error(["--listen", "127.0.0.1:%d" % sim.port], "port in use")


def test_help():
    rc, out, _ = run_sim("--help")
    assert rc == 0 and "--listen HOST:PORT" in out


def test_port_zero_prints_the_chosen_port():
    import subprocess
    p = subprocess.Popen([SIM, "--listen", "127.0.0.1:0"], stdout=subprocess.PIPE, text=True)
    try:
        line = p.stdout.readline()
        port = int(line.split("127.0.0.1:")[1].split()[0])
        assert port > 0 and "1:arm" in line
        with Bus("tcp://127.0.0.1:%d" % port) as bus:
            assert bus.ping(1) == 0
    finally:
        p.terminate()
        assert p.wait(timeout=5) == 0
        p.stdout.close()


def test_default_is_one_arm_with_id_1(sim_factory):
    sim = sim_factory()
    with Bus(sim.url) as bus:
        assert bus.ping(1) == 0
        assert bus.variant(1).name == "arm"


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_signals_end_it_cleanly(sim_factory, sig):
    sim = sim_factory("4:foot")
    with Bus(sim.url) as bus:
        bus.ping(4)
        assert sim.stop(sig) == 0


def test_one_client_at_a_time(sim_factory):
    sim = sim_factory()
    with Bus(sim.url) as first:
        first.ping(1)
        with Bus(sim.url) as second:
            with pytest.raises(ServoBusError, match="one client at a time"):
                second.ping(1)
        assert first.ping(1) == 0
    with Bus(sim.url) as later:  # the next client is served once the first has gone
        assert later.ping(1) == 0


def test_state_dir_files_are_created(sim_factory, tmp_path):
    state = tmp_path / "state"
    sim = sim_factory("1:arm", "5:base", state_dir=state)
    for name in ("servo-1-arm.flash", "servo-5-base.flash"):
        f = state / name
        # store (4 pages), application slot and staging slot (26 pages each), boot record
        assert f.stat().st_size == (4 + 26 + 26 + 1) * 1024
    sim.stop()


def test_state_dir_remembers_settings_across_sigkill(sim_factory, tmp_path):
    sim = sim_factory("5:arm", state_dir=tmp_path)
    with Bus(sim.url) as bus:
        assert bus.read(5, "id") == 5
        bus.write(5, "return_delay", 3)
        bus.write(5, "ccw_angle_limit", 200)
        bus.set_id(5, 6)
    sim.stop(signal.SIGKILL)  # a power cut
    sim = sim_factory("5:arm", state_dir=tmp_path)
    with Bus(sim.url) as bus:
        with pytest.raises(BusTimeout):
            bus.ping(5)
        assert bus.read_many(6, ["id", "return_delay", "ccw_angle_limit"]) == {
            "id": 6, "return_delay": 3, "ccw_angle_limit": 200}
        assert bus.read(6, "goal_position") == 0  # RAM: back to the power-up value


def test_state_dir_rejects_a_foreign_file(tmp_path):
    (tmp_path / "servo-1-arm.flash").write_bytes(b"\0" * 100)
    assert_usage_error(["--listen", "127.0.0.1:%d" % free_port(), "--state-dir",
                        str(tmp_path)], "servo-1-arm.flash", "100 bytes")


def test_state_file_is_locked(sim_factory, tmp_path):
    sim_factory("1:arm", state_dir=tmp_path)
    assert_usage_error(["--listen", "127.0.0.1:%d" % free_port(), "--state-dir",
                        str(tmp_path)], "in use by another servo-sim")


def test_without_state_dir_nothing_is_remembered(sim_factory, tmp_path):
    os.chdir(tmp_path)
    sim = sim_factory("5:arm")
    with Bus(sim.url) as bus:
        bus.write(5, "return_delay", 3)
    sim.stop()
    sim = sim_factory("5:arm")
    with Bus(sim.url) as bus:
        assert bus.read(5, "return_delay") == 16
    assert os.listdir(tmp_path) == []
