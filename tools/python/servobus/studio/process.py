"""Start `python3 -m servobus studio` as a child process (screenshots, browser tests)."""

import os
import selectors
import signal
import socket
import subprocess
import sys
import time

PYROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def free_port():
    """A TCP port nobody listens on right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def run_studio(*args, timeout=30):
    """Run `servoctl studio ARGS` to completion: (returncode, stdout, stderr)."""
    env = dict(os.environ, PYTHONPATH=PYROOT)
    p = subprocess.run([sys.executable, "-m", "servobus", "studio", *args],
                       capture_output=True, text=True, timeout=timeout, env=env)
    return p.returncode, p.stdout, p.stderr


class Studio:
    """A running studio on bus_url; .url is the page's address with the token, .base
    the address without it, .token the token."""

    def __init__(self, bus_url, *extra, start_timeout=30):
        for attempt in range(5):  # the free port may be taken before the studio binds it
            self.listen = "127.0.0.1:%d" % free_port()
            line = self._start(bus_url, extra, start_timeout)
            if "open http" in line:
                break
            self.stop()
            if "cannot listen" not in self.stderr:
                break
        else:
            line = ""
        if "open http" not in line:
            raise RuntimeError("the studio did not start: %s%s" % (line, self.stderr))
        self.banner = line.strip()
        # the address to open, with this process's token (studio/security.py)
        self.url = self.banner.split(" open ", 1)[1]
        self.token = self.url.split("?token=", 1)[1]
        self.base = "http://%s" % self.listen

    def _start(self, bus_url, extra, start_timeout):
        """Start it; the line it printed (the address when it serves)."""
        self.rc = None
        env = dict(os.environ, PYTHONPATH=PYROOT, PYTHONUNBUFFERED="1")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "servobus", "studio", "--port", bus_url,
             "--listen", self.listen, *extra],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
        sel = selectors.DefaultSelector()
        sel.register(self.proc.stdout, selectors.EVENT_READ)
        deadline = time.monotonic() + start_timeout
        line = ""
        while time.monotonic() < deadline and "open http" not in line:
            if not sel.select(timeout=deadline - time.monotonic()):
                break
            line = self.proc.stdout.readline()
            if not line:
                break
        sel.close()
        return line

    def stop(self):
        """SIGTERM (a clean stop); returns the exit status (again if already stopped)."""
        if getattr(self, "rc", None) is not None:
            return self.rc
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            rc = self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            rc = self.proc.wait()
        self.stderr = self.proc.stderr.read()
        self.stdout = self.proc.stdout.read()  # what it printed after the address
        self.proc.stdout.close()
        self.proc.stderr.close()
        self.rc = rc
        return rc
