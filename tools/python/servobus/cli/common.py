"""What every servoctl command shares: the usage error, notes on stderr, a register
shown with its unit, the heartbeat and flash-commit notes."""

import math
import os
import sys
import time

from ..errors import ServoBusError

PROG = "servoctl"


class UsageError(Exception):
    """Bad usage found by a command (exit status 2)."""


def state_path():
    """Where servoctl keeps its flash commit estimate between runs (budget.py)."""
    if os.environ.get("SERVOBUS_STATE"):
        return os.environ["SERVOBUS_STATE"]
    base = os.environ.get("XDG_STATE_HOME") or os.path.join(
        os.path.expanduser("~"), ".local", "state")
    return os.path.join(base, "servobus", "commit-budget.json")


def note(text):
    print("note: " + text, file=sys.stderr)


def show(reg, value, resolution):
    return "%s = %s" % (reg.name, "-" if value is None else reg.format(value, resolution))


def heartbeat_note(bus, servo_id):
    """Motion started by a one-shot command stops 500 ms after the last packet when the
    heartbeat (register 17, on by factory default) is enabled: say so."""
    try:
        on = bus.read(servo_id, "heartbeat_enable")
    except ServoBusError:
        return
    if on:
        print("note: heartbeat on (register 17): ID %d stops 500 ms after the last packet; "
              "use --wait or `monitor` to keep talking, or `set heartbeat_enable 0`" %
              servo_id, file=sys.stderr)


def wait_still(bus, servo_id, timeout):
    """Poll until the servo reports moving 0 (the polling keeps the heartbeat alive)."""
    deadline = time.monotonic() + timeout
    while bus.read(servo_id, "moving"):
        if time.monotonic() > deadline:
            raise ServoBusError("ID %d still moving after %.0f s" % (servo_id, timeout))
        time.sleep(0.05)


def commit_note(servo_id, waits):
    """Issue 19: the value is in force, but a commit past the servo's flash budget
    reaches flash later; say how long the power must stay on."""
    if not waits:
        return
    wait = max(waits)
    note("ID %d has used its burst of quick flash commits (estimate from this host's "
          "writes: 64 at once, then one per 64 s): the new value is in force now but "
          "reaches flash in up to %.0f s — do not cut the power before %s" % (
              servo_id, math.ceil(wait), time.strftime("%H:%M:%S",
                                                       time.localtime(time.time() + wait))))
