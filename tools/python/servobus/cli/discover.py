"""servoctl's commands about who is on the bus: scan, ping, set-id, reset."""

from .. import protocol as P
from ..discovery import IN_UPDATE_MODE
from ..errors import DuplicateId, IdTaken, ServoBusError
from ..registers import variant_by_model
from .common import UsageError, commit_note, note


def cmd_scan(bus, args):
    found = bus.scan(all_bauds=args.all_bauds, check_duplicates=True)
    for text in bus.scan_notes:
        note(text)
    bauds = "every baud" if args.all_bauds and not bus.is_tcp else "%d baud" % bus.baud
    if not found and bus.duplicates:
        raise DuplicateId("no servo answered a broadcast PING intact, and two servos "
                          "answer at ID %s: see \"Two servos on one ID\" in "
                          "tools/python/README.md" % ", ".join(map(str, bus.duplicates)))
    if not found:
        # Where cheap: one frame to the ID given (default 1) tells a servo in update mode.
        if not bus.scan_notes and bus.in_update_mode(args.id):
            raise ServoBusError("no servo answered a broadcast PING, but ID %d answers the "
                                "update handshake: %s — send a good image: `servoctl --id "
                                "%d update FILE`" % (args.id, IN_UPDATE_MODE, args.id))
        raise ServoBusError("no servo answered a broadcast PING at %s%s" % (
            bauds, "" if args.all_bauds else " (try --all-bauds)"))
    print("%d servo%s found at %s:" % (len(found), "" if len(found) == 1 else "s", bauds))
    print("%4s  %-7s  %7s  %s" % ("ID", "variant", "baud", "status"))
    for f in found:
        status = "ok" if not f.err else ", ".join(P.describe_err(f.err))
        if f.id in bus.duplicates:
            status = "TWO SERVOS ON THIS ID"
        print("%4d  %-7s  %7s  %s" % (f.id, _variant_name(bus, f), "tcp" if bus.is_tcp
                                      else f.baud, status))
    if bus.duplicates:
        raise DuplicateId("two servos answer at ID %s: anything sent to that ID reaches "
                          "both; see \"Two servos on one ID\" in tools/python/README.md"
                          % ", ".join(map(str, bus.duplicates)))
    return 0


def _variant_name(bus, f):
    """The variant of the servo found as f, asked at its baud ('?' if it does not say;
    not from the per-ID cache: two servos may share the ID at two bauds)."""
    start = bus.baud
    try:
        if f.baud != bus.baud:
            bus.set_baud(f.baud)
        v = variant_by_model(bus.read(f.id, "model_number"))
        return v.name if v else "?"
    except ServoBusError:
        return "?"
    finally:
        if bus.baud != start:
            bus.set_baud(start)


def cmd_ping(bus, args):
    err = bus.ping(args.id)  # no answer: BusTimeout, naming update mode when it is that
    if bus.duplicate(args.id):
        raise DuplicateId("two servos answer at ID %d (two answers to one PING, or "
                          "answers garbled by each other): see \"Two servos on one ID\" "
                          "in tools/python/README.md" % args.id)
    print("ID %d: present, %s" % (args.id, "no errors" if not err else
                                    "reports " + ", ".join(P.describe_err(err))))
    return 0


def cmd_set_id(bus, args):
    try:
        bus.set_id(args.id, args.new_id, check_free=not args.force)
    except IdTaken as e:
        raise IdTaken("%s (or add --force)" % e) from None
    print("ID %d is now ID %d%s" % (args.id, args.new_id, "" if bus.confirmed else
                                    " (it answers PING there)"))
    commit_note(args.new_id, [bus.commit_wait] if bus.commit_wait else [])
    return 0


def cmd_reset(bus, args):
    if not args.yes:
        raise UsageError("reset restores every register of ID %d to its factory value "
                         "(ID 1, default baud); add --yes to do it" % args.id)
    try:
        bus.reset(args.id, check_free=not args.force)  # succeeds only on proof from it
    except IdTaken as e:
        raise IdTaken("reset would move ID %d to ID 1: %s (or add --force)" % (
            args.id, e)) from None
    print("ID %d: reset to factory values; it now answers at ID 1 and its default baud" %
          args.id)
    commit_note(1, [bus.commit_wait] if bus.commit_wait else [])
    return 0
