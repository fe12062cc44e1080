"""servoctl: command line for the servo bus (python3 -m servobus, or the servoctl script).

Exit status: 0 done; 1 the bus or a servo said no, or a check on the bus failed (a
time-out, a refusal, two servos on one ID); 2 refused before anything was sent: bad
usage, a value out of range or not for the servo's variant, an unreadable or invalid
firmware image, or a setting that needs --force (or --yes). Every failure is one line on
stderr.

The commands live by job: discover.py (scan, ping, set-id, reset), table.py (get, set,
dump), moving.py (move, speed, stop, home, traj), monitor.py, firmware.py (update);
args.py builds the parser."""

import os
import re
import sys

from .. import image as I
from .. import protocol as P
from ..budget import CommitBudget
from ..bus import Bus
from ..errors import IdTaken, RangeError, ServoBusError, UnknownRegister
from .args import build_parser
from .common import PROG, UsageError, note, state_path


_MOVING = ("move", "speed", "traj", "home")


def _interrupted(bus, args):
    """The one line Ctrl-C leaves: what is still going on, and how to stop it."""
    step = getattr(bus, "update_step", None) if bus is not None else None
    sid = getattr(args, "id", 1)
    if step in ("end of batch", "restart"):
        return ("interrupted after the image was sent: ID %d is checking and installing "
                "it; PING it in a few seconds (`servoctl --id %d ping`)" % (sid, sid))
    if step is not None:
        return ("interrupted during the update (at the %s): ID %d's update session ends "
                "10 s after the last frame, and until then it refuses every command but "
                "PING and READ; it keeps its firmware (a servo in update mode stays "
                "there): run the update again" % (step, sid))
    if getattr(args, "command", None) in _MOVING:
        return ("interrupted: ID %d may still be moving — `servoctl --id %d stop` stops "
                "it (with the heartbeat on, register 17, it stops by itself 500 ms after "
                "the last packet)" % (sid, sid))
    return "interrupted"


def _fault_note(bus, args):
    """Live fault bits seen in answers: the command went through, but say so (a latched
    protection unload refuses motion until cleared)."""
    if args.command in ("ping", "scan", "monitor") or not bus.faults:
        return
    for servo_id in sorted(bus.faults):
        try:
            err = bus.ping(servo_id) & P.ERR_FAULTS  # live now, after the command?
        except ServoBusError:
            continue
        if not err:
            continue
        note("ID %d reports %s: a protection unload stays latched (torque off, motion "
              "refused) until the cause is gone and `servoctl --id %d set clear_unload 1`"
              % (servo_id, ", ".join(P.describe_err(err & P.ERR_FAULTS)), servo_id))


def main(argv=None):
    # Every line as it happens, into a pipe too (`servoctl move --wait | tee log`, a GUI
    # reading its output): a progress line held in a buffer until exit tells nobody
    # anything, and a Ctrl-C would find it unprinted.
    if hasattr(sys.stdout, "reconfigure"):
        sys.stdout.reconfigure(line_buffering=True)
    argv = sys.argv[1:] if argv is None else list(argv)
    # A negative value (-100, -45deg/s) is a value, not an option: a leading space keeps
    # argparse from taking it for one, and the value parsers ignore it.
    argv = [" " + a if re.match(r"-\.?\d", a) else a for a in argv]
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as e:
        return e.code if isinstance(e.code, int) else 2
    port = getattr(args, "port", None) or os.environ.get("SERVOBUS_PORT")
    args.id = getattr(args, "id", 1)
    args.force = getattr(args, "force", False)
    if not port:
        print("%s: no bus given: use --port tcp://HOST:PORT (servo-sim) or --port "
              "/dev/ttyUSB0, or set SERVOBUS_PORT" % PROG, file=sys.stderr)
        return 2
    bus = None
    try:
        if getattr(args, "prepare", None):
            args.prepare(args)
        with Bus(port, baud=getattr(args, "baud", 9600), timeout=getattr(args, "timeout", None),
                 raise_faults=False) as bus:
            bus.commit_budget = CommitBudget(state_path())
            rc = args.func(bus, args)
            _fault_note(bus, args)
            return rc
    except (UsageError, RangeError, UnknownRegister, IdTaken, I.ImageError) as e:
        return _fail(e, 2)  # refused before anything was sent
    except ServoBusError as e:
        return _fail(e, 1)
    except KeyboardInterrupt:
        print("%s: %s" % (PROG, _interrupted(bus, args)), file=sys.stderr)
        return 130
    except OSError as e:  # a serial adapter unplugged mid-command, a full disk for --plot
        return _fail("%s: %s" % (getattr(e, "filename", None) or port, e.strerror or e), 1)


def _fail(e, status):
    print("%s: %s" % (PROG, " ".join(str(e).split())), file=sys.stderr)
    return status
