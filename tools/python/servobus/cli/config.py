"""servoctl config save|restore|diff: a servo's settings as a JSON file (servobus/config.py,
shared with Servo Studio's configuration panel)."""

import os
import re

from .. import config as C
from ..errors import RangeError
from ..registers import REGISTERS
from .common import UsageError, commit_note, note
from .table import _check_new_id, lockout_checks


def cmd_config(bus, args):
    return {"save": _save, "restore": _restore, "diff": _diff}[args.action](bus, args)


def _one(args, what):
    if len(args.sources) != 1:
        raise UsageError("config %s takes one FILE" % what)
    return args.sources[0]


def _save(bus, args):
    path = _one(args, "save")
    doc = C.save(bus, args.id)
    C.dump(doc, path)
    print("ID %d (%s, model 0x%04X, firmware %d): %d settings saved to %s" % (
        args.id, doc["variant"], doc["model_number"], doc["firmware_version"],
        len(doc["settings"]), path))
    return 0


def _restore(bus, args):
    doc = C.load(_one(args, "restore"))
    changes, _, runs = C.restore_plan(bus, args.id, doc, args.with_id, args.with_baud)
    if not changes:
        print("ID %d already has these settings: nothing written" % args.id)
        return 0
    if not args.force:
        lockout_checks(bus, args, changes)
    if changes.get("id", args.id) != args.id:
        _check_new_id(bus, args, changes["id"])
    for name, value in changes.items():
        print("%s = %s%s" % (name, REGISTERS[name].format(value, doc["settings"].get(
            "angle_resolution", 10)), " (not written: --dry-run)" if args.dry_run else ""))
    if args.dry_run:
        return 0
    C.restore(bus, args.id, changes)
    print("ID %d: %d settings restored in %d WRITEs%s" % (
        args.id, len(changes), len(runs), "" if bus.confirmed else
        " (not confirmed: its status return level keeps it silent)"))
    if "id" in changes:
        print("ID %d is now ID %d" % (args.id, changes["id"]))
    if "baud_rate" in changes:
        note("ID %d may now answer at another baud: add --baud to later commands" %
             changes.get("id", args.id))
    commit_note(args.id, [bus.commit_wait] if bus.commit_wait else [])
    return 0


def _source(bus, text, default_id):
    """A configuration from a file, or from a servo ('id:N' or N)."""
    m = re.fullmatch(r"(?:id:)?(\d+)", text)
    if m and not os.path.exists(text):
        sid = int(m.group(1))
        if sid > 253:
            raise RangeError("ID %d is out of range 0-253" % sid)
        return "ID %d" % sid, C.save(bus, sid)
    if text == "-":
        return "ID %d" % default_id, C.save(bus, default_id)
    return text, C.load(text)


def _diff(bus, args):
    if not 1 <= len(args.sources) <= 2:
        raise UsageError("config diff takes one or two of FILE, ID (id:N)")
    sources = args.sources if len(args.sources) == 2 else ["-", args.sources[0]]
    (na, a), (nb, b) = (_source(bus, s, args.id) for s in sources)
    rows = C.diff(a, b)
    if not rows:
        print("%s and %s have the same settings" % (na, nb))
        return 0
    print("%-22s  %-12s  %s" % ("setting", na, nb))
    for name, va, vb in rows:
        print("%-22s  %-12s  %s" % (name, "-" if va is None else va,
                                    "-" if vb is None else vb))
    return 1
