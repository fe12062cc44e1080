"""A servo's settings as a file (issue 29: `servoctl config save|restore|diff` and Servo
Studio's configuration panel).

save() reads a servo's EEPROM settings (the writable EEPROM registers of its variant)
with its variant, model number and firmware version. restore_plan() checks a file
against another servo before anything is sent: the same variant, every value through
the SDK's validator (Bus.plan_write: range, variant, CW <= CCW), the ID and the baud
only when asked, only the settings that differ (traffic that changes nothing writes
nothing), the lock-out rules (Bus.lockout) and the flash commit budget (budget.py:
refused when the WRITEs it takes exceed the commits the servo can make at once, so
nothing is left waiting for flash). restore() then writes them all or nothing
(Bus.write_many). diff() compares two sets of settings."""

import json

from . import values as V
from .errors import RangeError
from .registers import REGISTERS, TABLE_SIZE, decode_table, variant_by_model

FORMAT = "servobus-config/1"
MOVES_SERVO = ("id", "baud_rate")  # restored only when asked


def setting_registers(variant):
    """The registers a configuration file holds for a variant: writable EEPROM ones."""
    return [r for r in REGISTERS.values()
            if r.area == "EEPROM" and r.writable and r.applies_to(variant)]


def save(bus, servo_id):
    """The configuration of servo_id: a dict ready for json.dump (one READ)."""
    data = bus.read_alone(servo_id, 0, TABLE_SIZE)
    variant = variant_by_model(int.from_bytes(data[0:2], "little"))
    if variant is None:
        raise RangeError("ID %d has model number 0x%04X, which this SDK does not know: "
                         "its settings cannot be saved by name" % (
                             servo_id, int.from_bytes(data[0:2], "little")))
    values = decode_table(data, variant=variant)
    return {
        "format": FORMAT, "variant": variant.name, "model_number": values["model_number"],
        "firmware_version": values["firmware_version"], "saved_from_id": servo_id,
        "settings": {r.name: values[r.name] for r in setting_registers(variant)},
    }


def check(doc):
    """A configuration read from a file, checked: RangeError with a sentence for what
    is not one (format, variant, a register not of that variant, a value out of range)."""
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise RangeError("not a servo configuration file (its \"format\" is not %r)" %
                         FORMAT)
    from .registers import VARIANTS
    given = doc.get("variant")
    variant = VARIANTS.get(given) if isinstance(given, str) else None  # a list: no 500
    if variant is None:
        raise RangeError("the file's variant %r is not one of %s" % (
            doc.get("variant"), ", ".join(VARIANTS)))
    settings = V.mapping(doc.get("settings"), "the file's settings")
    names = {r.name for r in setting_registers(variant)}
    for name, value in settings.items():
        if name not in names:
            raise RangeError("the file's %r is not a setting of the %s" % (
                name, variant.name))
        REGISTERS[name].encode(V.strict_integer(value, name))
    return variant


def load(path):
    """A configuration file, checked (RangeError for one that is not)."""
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    except (OSError, ValueError) as e:
        raise RangeError("%s: %s" % (path, getattr(e, "strerror", None) or e)) from None
    check(doc)
    return doc


def dump(doc, path):
    with open(path, "w", encoding="utf-8") as f:
        json.dump(doc, f, indent=2, sort_keys=False)
        f.write("\n")


def restore_plan(bus, servo_id, doc, with_id=False, with_baud=False):
    """What restoring doc onto servo_id would write, checked before anything is sent:
    (changes {register: value}, lock-out sentences, the WRITEs it takes). RangeError for
    another variant, a value the validator refuses, or a commit budget too small."""
    variant = check(doc)
    target = save(bus, servo_id)
    if target["variant"] != variant.name:
        raise RangeError("the file is for the %s, ID %d is the %s: settings go only onto a "
                         "servo of the same variant" % (variant.name, servo_id,
                                                         target["variant"]))
    skip = {"id"} if not with_id else set()
    if not with_baud:
        skip.add("baud_rate")
    changes = {n: v for n, v in doc["settings"].items()
               if n not in skip and target["settings"].get(n) != v}
    if not changes:
        return {}, [], []
    runs = bus.plan_write(servo_id, changes)
    tokens = bus.commit_budget.tokens(bus.budget_key(servo_id))
    if len(runs) > tokens:
        raise RangeError(
            "restoring takes %d WRITEs to flash but ID %d can commit %d at once now "
            "(estimate: 64 at once, one more every 64 s): wait %d s and try again, so that "
            "nothing is left waiting for flash" % (len(runs), servo_id, tokens,
                                                   64 * (len(runs) - tokens)))
    return changes, bus.lockout(servo_id, changes), runs


def restore(bus, servo_id, changes):
    """Write what restore_plan() returned (all or nothing: Bus.write_many)."""
    if changes:
        bus.write_many(servo_id, changes)
    return changes


def diff(a, b):
    """[(register, value in a, value in b)] where two configurations differ (None: not
    in that one), in address order; the variant, model and firmware version too."""
    out = []
    for key in ("variant", "model_number", "firmware_version"):
        if a.get(key) != b.get(key):
            out.append((key, a.get(key), b.get(key)))
    sa, sb = a.get("settings", {}), b.get("settings", {})
    for name in sorted(set(sa) | set(sb), key=lambda n: REGISTERS[n].address
                       if n in REGISTERS else 999):
        if sa.get(name) != sb.get(name):
            out.append((name, sa.get(name), sb.get(name)))
    return out
