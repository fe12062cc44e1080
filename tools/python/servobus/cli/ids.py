"""servoctl ids [--fix] and servoctl adopt --expect 1,2,3,4 (issue 27): every servo by
its unique identity, duplicates and factory-fresh servos included, with no unplugging."""

import collections
import json
import os

from ..errors import DuplicateId, ServoBusError
from ..ids import uid_text
from .common import UsageError, note, state_path


def _known_path():
    """Where servoctl remembers which UID had which ID on each port (adopt uses it to
    tell an old servo from a new one on one ID): beside the commit budget's state."""
    return os.path.join(os.path.dirname(state_path()), "known-uids.json")


def load_known(port):
    try:
        with open(_known_path()) as f:
            data = json.load(f).get(port, {})
        return {bytes.fromhex(k): int(v) for k, v in data.items()}
    except (OSError, ValueError, AttributeError):
        return {}


def save_known(port, idents):
    """Remember the servos of a bus whose IDs are all distinct (a bus in order)."""
    ids = [i.id for i in idents]
    if len(set(ids)) != len(ids):
        return
    path = _known_path()
    try:
        with open(path) as f:
            data = json.load(f)
    except (OSError, ValueError):
        data = {}
    data[port] = {uid_text(i.uid): i.id for i in idents}
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path + ".tmp", "w") as f:
            json.dump(data, f)
        os.replace(path + ".tmp", path)
    except OSError as e:
        note("could not remember the UIDs in %s: %s" % (path, e.strerror or e))


def _table(idents):
    count = collections.Counter(i.id for i in idents)
    print("%-24s  %4s  %-7s  %6s  %7s  %s" % ("UID", "ID", "variant", "model", "baud",
                                              "status"))
    for i in idents:
        status = "DUPLICATE ID" if count[i.id] > 1 else "ok"
        print("%-24s  %4d  %-7s  %6d  %7s  %s" % (uid_text(i.uid), i.id, i.variant, i.model,
                                                 i.baud, status))
    return sorted(sid for sid, n in count.items() if n > 1)


def cmd_ids(bus, args):
    idents = bus.enumerate()
    if not idents:
        raise ServoBusError("no servo answered ENUMERATE at %d baud" % bus.baud)
    print("%d servo%s found at %d baud (%d rounds):" % (
        len(idents), "" if len(idents) == 1 else "s", bus.baud, bus.enumerate_rounds))
    shared = _table(idents)
    if not shared:
        save_known(bus.port, idents)
        return 0
    if not args.fix:
        raise DuplicateId("two or more servos share ID %s: `servoctl ids --fix` gives each "
                          "a free ID (the lowest UID keeps the old one)"
                          % ", ".join(map(str, shared)))
    for uid, old, new in bus.fix_duplicates(idents):
        print("UID %s: ID %d -> %d" % (uid_text(uid), old, new))
    idents = bus.enumerate()
    print("now:")
    if _table(idents):
        raise DuplicateId("IDs are still shared after --fix")
    save_known(bus.port, idents)
    return 0


def _expect(text):
    try:
        ids = [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        ids = []
    if not ids or any(not 0 <= i <= 253 for i in ids):
        raise UsageError("--expect %r: give IDs 0-253 separated by commas, e.g. 1,2,3,4"
                         % text)
    return ids


def cmd_adopt(bus, args):
    expect = _expect(args.expect)
    uid, new = bus.adopt(expect, known=load_known(bus.port))
    print("UID %s adopted as ID %d at %d baud" % (uid_text(uid), new, bus.baud))
    save_known(bus.port, bus.enumerate())
    return 0


def add_commands(add):
    sp = add("ids", cmd_ids, "list every servo by unique ID (UID), duplicates marked")
    sp.add_argument("--fix", action="store_true",
                    help="give every servo that shares an ID a free one (lowest UID keeps it)")
    sp = add("adopt", cmd_adopt,
             "give a replacement servo the one missing expected ID and this bus's baud")
    sp.add_argument("--expect", required=True, metavar="ID,ID,...",
                    help="the IDs the bus should have, e.g. 1,2,3,4")
