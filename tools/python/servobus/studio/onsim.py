"""`make studio`: servo-sim with an arm, a foot and a base, and the studio on it.

    python3 -m servobus.studio.onsim [SERVO_SIM] [--listen HOST:PORT]

Prints the address to open; Ctrl-C stops the studio and servo-sim."""

import argparse
import os
import selectors
import subprocess
import sys

from . import DEFAULT_LISTEN
from .process import PYROOT, free_port

REPO = os.path.dirname(os.path.dirname(PYROOT))
SERVOS = ("1:arm", "2:foot", "3:base")


def start_sim(sim, servos=SERVOS, state_dir=None):
    """Start servo-sim on a free port: (Popen, 'tcp://127.0.0.1:PORT')."""
    if not os.access(sim, os.X_OK):
        raise SystemExit("%s is missing: build it with `make host`" % sim)
    port = free_port()
    args = [sim, "--listen", "127.0.0.1:%d" % port]
    for s in servos:
        args += ["--servo", s]
    if state_dir:
        args += ["--state-dir", str(state_dir)]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, text=True)
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ)
    line = proc.stdout.readline() if sel.select(timeout=10) else ""
    sel.close()
    if "listening on" not in line:
        proc.kill()
        raise SystemExit("servo-sim did not start (%s)" % line.strip())
    return proc, "tcp://127.0.0.1:%d" % port


def main(argv=None):
    ap = argparse.ArgumentParser(prog="make studio", description=__doc__.split("\n")[0])
    ap.add_argument("sim", nargs="?", default=os.path.join(REPO, "build", "host",
                                                           "servo-sim"))
    ap.add_argument("--listen", default=DEFAULT_LISTEN)
    args = ap.parse_args(argv)
    proc, url = start_sim(args.sim)
    print("servo-sim on %s: ID 1 arm, ID 2 foot, ID 3 base" % url, flush=True)
    try:
        from .. import Bus
        from .server import serve
        with Bus(url) as bus:
            return serve(bus, args.listen)
    finally:
        proc.terminate()
        proc.wait()


if __name__ == "__main__":
    sys.exit(main())
