"""servoctl's control-table commands: get, set (all or nothing, lock-out checks) and
dump. get and dump read the whole table in one READ and listen for its whole answer
window: two servos at one ID are refused (DuplicateId, exit 1), never mixed."""

from ..errors import DuplicateId, IdTaken, RangeError, ServoBusError
from ..registers import REGISTERS, TABLE_SIZE, baud_of_code, decode_table, register, \
    variant_by_model
from ..protection import CLEAR_RETRY_S
from .common import UsageError, commit_note, note, show

_LOCKOUT_TAILS = {
    "status_return_level": "servoctl still reaches it: `set status_return_level 2`",
    "temperature_limit": "`set temperature_limit N clear_unload 1` undoes it",
}


def cmd_get(bus, args):
    regs = [register(r) for r in args.registers]
    for r in regs:
        if not r.readable:
            raise RangeError("%s (register %d) is write-only: it reads 0 whatever was "
                             "written" % (r.name, r.address))
    table = bus.read_alone(args.id, 0, TABLE_SIZE)  # one servo's values, all at once
    variant = variant_by_model(int.from_bytes(table[0:2], "little"))
    values = decode_table(table, variant=variant)
    for r in regs:
        if not r.applies_to(variant):
            raise RangeError("%s (register %d) does not exist on the %s (it is for %s)" % (
                r.name, r.address, variant.name, ", ".join(r.variants)))
    resolution = values["angle_resolution"] or 10
    for r in regs:
        print(values[r.name] if args.raw else show(r, values[r.name], resolution))
    return 0


def _new_baud(bus, servo_id, code):
    """The baud a register 4 code gives this servo (code 0: its variant's default)."""
    try:
        variant = bus.variant(servo_id)
    except ServoBusError:
        variant = None
    return baud_of_code(code, variant)


def lockout_checks(bus, args, values):
    """The SDK's lock-out rules (Bus.lockout, shared with Servo Studio): a setting
    after which servoctl could no longer reach the servo as it is called now is
    refused without --force (usage error), with the way back in the message."""
    for reason in bus.lockout(args.id, values):
        name = reason.split()[0]
        tail = _LOCKOUT_TAILS.get(name, "")
        if name == "baud_rate":
            tail = "every later command needs --baud %d" % _new_baud(
                bus, args.id, values["baud_rate"])
        raise UsageError("%s%s; add --force to write it" % (reason, "; " + tail if tail
                                                            else ""))


def _parse_pairs(bus, args):
    """{register name: value} from REGISTER VALUE pairs, every value checked; and the
    angle resolution the values were read with."""
    if len(args.pairs) % 2:
        raise RangeError("set takes REGISTER VALUE pairs; '%s' has no value" % args.pairs[-1])
    pairs = [(register(args.pairs[i]), args.pairs[i + 1]) for i in range(0, len(args.pairs), 2)]
    resolution = 10
    if any(r.unit in ("position", "speed", "dir_speed") for r, _ in pairs):
        resolution = bus.resolution(args.id) or 10
    values = {}
    for r, text in pairs:  # every value checked before anything is sent
        if r.name in values:
            raise RangeError("%s is given twice" % r.name)
        values[r.name] = r.parse(text, resolution)
    return values, resolution


def _check_new_id(bus, args, new_id):
    """A new ID goes to one servo, and (without --force) to an ID that is free at every
    baud the port reaches."""
    if bus.duplicate(args.id):
        raise DuplicateId("two servos answer at ID %d: a new ID would go to both (see "
                          "\"Two servos on one ID\" in tools/python/README.md)" % args.id)
    if not args.force:
        try:
            bus.refuse_taken(new_id)
        except IdTaken as e:
            raise IdTaken("%s (or add --force)" % e) from None


def cmd_set(bus, args):
    values, resolution = _parse_pairs(bus, args)
    rest = {k: v for k, v in values.items() if k != "clear_unload"}
    if rest:
        bus.plan_write(args.id, rest)  # range, variant, CW <= CCW: before anything is sent
    if not args.force:
        lockout_checks(bus, args, values)
    new_id = values.get("id", args.id)
    if new_id != args.id:
        _check_new_id(bus, args, new_id)
    bus.write_many(args.id, values)  # a clear_unload last, retried alone (Bus.clear_unload)
    wait, confirmed = bus.commit_wait, bus.confirmed
    for name, value in values.items():
        r = REGISTERS[name]
        text = show(r, value, resolution)
        if name == "clear_unload" and (bus.clear_took or 0) > 2 * CLEAR_RETRY_S:
            text += " (after %.1f s: the servo still saw the cause for that long)" % (
                bus.clear_took)
        if name == "goal_position" and confirmed:
            held = bus.read(new_id, r)
            if held != value:
                text += " (the servo holds %s: clamped to its angle limits)" % r.format(
                    held, resolution)
        print("%s: written%s" % (text, "" if confirmed else " (not confirmed: at status "
                                 "return level %d ID %d does not answer writes)" % (
                                     bus.known_level(new_id), new_id)))
    if new_id != args.id:
        print("ID %d is now ID %d" % (args.id, new_id))
    if "baud_rate" in values:
        baud = _new_baud(bus, new_id, values["baud_rate"])
        if baud != bus.baud:
            note("ID %d now answers at %d baud: add --baud %d to later commands" % (
                new_id, baud, baud))
    commit_note(new_id, [wait] if wait else [])
    return 0


def cmd_dump(bus, args):
    rows = bus.dump(args.id)  # one READ; two servos at the ID: DuplicateId
    variant = bus.variant(args.id)  # known from that READ's model number
    values = {r.name: v for r, v in rows}
    resolution = values.get("angle_resolution") or 10
    print("ID %d: %s (model 0x%04X), firmware %s" % (
        args.id, variant.name if variant else "unknown variant", values["model_number"],
        values["firmware_version"]))
    print("%5s  %-22s  %-26s  %-6s  %s" % ("addr", "name", "value", "access", "area"))
    for r, v in rows:
        addr = "%d-%d" % (r.address, r.address + 1) if r.size == 2 else str(r.address)
        if v is None:
            text = "(write-only)" if r.applies_to(variant) else "(not on this variant)"
        else:
            text = r.format(v, resolution)
        print("%5s  %-22s  %-26s  %-6s  %s" % (addr, r.name, text, r.access, r.area))
    return 0
