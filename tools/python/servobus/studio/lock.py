"""One studio process per bus: a lock file per port, held for the process's life."""

import fcntl
import os
import re
import tempfile


def lock_path(port):
    """The lock file that makes one studio process own one bus. A serial device is
    named by its real path: /dev/serial/by-id/... and /dev/ttyUSB0 are one adapter
    (before, two studios opened it under two names and interleaved on the wire)."""
    if "://" not in port:
        port = os.path.realpath(port)
    safe = re.sub(r"[^A-Za-z0-9]+", "_", port).strip("_")
    return os.path.join(tempfile.gettempdir(), "servobus-studio-%s.lock" % safe)


class PortInUse(Exception):
    pass


def take_port(port, url):
    """Hold the port's lock for this process's life; PortInUse says who has it."""
    path = lock_path(port)
    f = open(path, "a+")
    try:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        f.seek(0)
        who = f.read().strip() or "another process"
        f.close()
        raise PortInUse("port %s is in use: %s already owns it. Open that studio in your "
                        "browser, or stop it first (one program at a time drives a bus)"
                        % (port, who)) from None
    f.seek(0)
    f.truncate()
    f.write("Servo Studio (process %d, %s)" % (os.getpid(), url))
    f.flush()
    return f
