"""Fixtures: start build/host/servo-sim (or $SERVO_SIM) on a free port and stop it."""

import os
import selectors
import signal
import socket
import subprocess
import sys
import tempfile
import time

import pytest
from hypothesis import settings

HERE = os.path.dirname(os.path.abspath(__file__))
PYROOT = os.path.dirname(HERE)  # tools/python
REPO = os.path.dirname(os.path.dirname(PYROOT))
SIM = os.environ.get("SERVO_SIM") or os.path.join(REPO, "build", "host", "servo-sim")

sys.path.insert(0, PYROOT)
# servoctl keeps its flash commit estimate (servobus/budget.py) in a state file: the
# tests' own, fresh for every run, never the user's. Hypothesis keeps no example database
# and its caches there too: nothing is written into the source tree.
_SCRATCH = tempfile.mkdtemp(prefix="servobus-test-")
os.environ["SERVOBUS_STATE"] = os.path.join(_SCRATCH, "commit-budget.json")
os.environ["HYPOTHESIS_STORAGE_DIRECTORY"] = os.path.join(_SCRATCH, "hypothesis")
settings.register_profile("servobus", database=None)
settings.load_profile("servobus")


def free_port():
    """A port nobody listens on right now (bind to port 0 and let the kernel choose)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def run_sim(*args, timeout=10):
    """Run servo-sim to completion (for argument errors): (returncode, stdout, stderr)."""
    p = subprocess.run([SIM, *args], capture_output=True, text=True, timeout=timeout)
    return p.returncode, p.stdout, p.stderr


class Sim:
    """A running servo-sim. url is tcp://127.0.0.1:PORT."""

    def __init__(self, servos=(), state_dir=None, port=None, extra=()):
        self.args = list(extra)
        for s in servos:
            self.args += ["--servo", s]
        if state_dir:
            self.args += ["--state-dir", str(state_dir)]
        for attempt in range(5):
            self.port = port if port is not None else free_port()
            if self._start():
                return
            if port is not None or "in use" not in self.stderr:
                break
        raise RuntimeError("servo-sim did not start: %s" % self.stderr)

    def _start(self):
        if not os.access(SIM, os.X_OK):
            pytest.fail("%s is missing: build it with `cmake --build --preset host`" % SIM)
        self.proc = subprocess.Popen(
            [SIM, "--listen", "127.0.0.1:%d" % self.port, *self.args],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        sel = selectors.DefaultSelector()
        sel.register(self.proc.stdout, selectors.EVENT_READ)
        ready = sel.select(timeout=10)
        sel.close()
        line = self.proc.stdout.readline() if ready else ""
        if "listening on" in line:
            self.banner = line
            self.stderr = ""
            return True
        self.proc.kill()
        self.proc.wait()
        self.stderr = self.proc.stderr.read()
        return False

    @property
    def url(self):
        return "tcp://127.0.0.1:%d" % self.port

    def stop(self, sig=signal.SIGTERM):
        """Stop it with sig; returns the exit status."""
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        try:
            rc = self.proc.wait(timeout=5)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
                self.proc.wait()
            self.proc.stdout.close()
            self.proc.stderr.close()
        return rc


@pytest.fixture
def sim_factory():
    """Start servo-sims; each is stopped at the end of the test."""
    sims = []

    def start(*servos, state_dir=None, port=None, extra=()):
        s = Sim(servos, state_dir, port, extra)
        sims.append(s)
        return s

    yield start
    for s in sims:
        if s.proc.returncode is None:
            s.stop(signal.SIGKILL)


# One mixed bus shared by the tests that leave it as they found it.
BUS_SERVOS = ("1:arm", "2:foot", "3:base", "7:wrist", "200:finger")
BUS_IDS = [1, 2, 3, 7, 200]


@pytest.fixture(scope="module")
def shared_sim():
    s = Sim(BUS_SERVOS)
    yield s
    assert s.stop() == 0


@pytest.fixture
def bus(shared_sim):
    from servobus import Bus
    with Bus(shared_sim.url) as b:
        yield b


def wait_until(predicate, timeout=3.0, poll=0.02):
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value or time.monotonic() > deadline:
            return value
        time.sleep(poll)
