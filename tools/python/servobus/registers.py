"""The control table as the firmware defines it: loaded from registers.json, which is
generated from src/regs.c by `regdoc --json` (a CTest checks the copy). Units, ranges,
variants and conversions between raw values and physical ones."""

import json
import math
import os
import re

from . import values as V
from .errors import RangeError, UnknownRegister

_JSON = os.path.join(os.path.dirname(os.path.abspath(__file__)), "registers.json")

with open(_JSON, encoding="ascii") as _f:
    _DATA = json.load(_f)

TABLE_SIZE = _DATA["table_size"]
BAUD_RATES = list(_DATA["baud_rates"])  # register 4 codes 1-10
UNIT_TEXT = dict(_DATA["units"])


class Variant:
    """A motor variant (board): name, letter, model number, defaults."""

    def __init__(self, d):
        self.name = d["name"]
        self.letter = d["letter"]
        self.model_number = d["model_number"]
        self.default_baud = d["default_baud"]
        self.return_delay = d["return_delay"]
        self.max_angle_ddeg = d["max_angle_ddeg"]
        self.photo_switches = d["photo_switches"]

    @property
    def position_register(self):
        """The register that holds the present position (§8)."""
        present = REGISTERS["present_position"]
        return present if present.applies_to(self) else REGISTERS["turned_angle"]

    def __repr__(self):
        return "Variant(%s)" % self.name


VARIANTS = {d["name"]: Variant(d) for d in _DATA["variants"]}
# Every board of the firmware's one list (cmake/boards.cmake) by name: its model number
# and its variant's name. A variant may have several boards, each its own model number.
BOARDS = {d["name"]: d for d in _DATA["boards"]}
_BY_MODEL = {b["model_number"]: VARIANTS[b["variant"]] for b in BOARDS.values()}


def variant_by_model(model_number):
    """The variant of a model number, or None for a model this SDK does not know."""
    return _BY_MODEL.get(model_number)


def baud_of_code(code, variant=None):
    """Baud rate of a register 4 code (0 = the variant's default, 9600 if unknown)."""
    if code == 0:
        return variant.default_baud if variant else 9600
    return BAUD_RATES[code - 1]


class Register:
    """One register of the control table."""

    def __init__(self, d):
        self.address = d["address"]
        self.name = d["name"]
        self.size = d["size"]
        self.access = d["access"]
        self.area = d["area"]
        self.variants = tuple(d["variants"])
        self.default = dict(d["default"])
        self.min = d["min"]
        self.max = d["max"]
        self.unit = d["unit"]
        self.signed = d["signed"]
        self.doc = d["doc"]

    readable = property(lambda self: "R" in self.access)
    writable = property(lambda self: "W" in self.access)

    def applies_to(self, variant):
        return variant is None or variant.name in self.variants

    # Raw (wire) value <-> value in the register's own unit (signed where it is).

    def decode(self, raw):
        """The register's value from its raw bytes' integer: two's complement for signed
        registers, bit 15 direction for speeds, bit 7 sign for temperatures."""
        if self.signed and raw & (1 << (8 * self.size - 1)):
            return raw - (1 << (8 * self.size))
        if self.unit == "dir_speed" and raw & 0x8000:
            return -(raw & 0x7FFF)
        if self.unit == "temperature" and raw & 0x80:
            return -(raw & 0x7F)
        return raw

    def encode(self, value):
        """The raw value for a value in the register's unit; RangeError (nothing sent) if
        it does not fit the register's range."""
        V.strict_integer(value, self.name)
        lo, hi = self.value_range()
        if not lo <= value <= hi:
            raise RangeError("%s: %d is out of range %d..%d%s" % (
                self.name, value, lo, hi, self._range_note()))
        if self.unit == "dir_speed" and value < 0:
            return 0x8000 | -value
        if self.unit == "temperature" and value < 0:
            return 0x80 | -value
        if self.signed and value < 0:
            return value + (1 << (8 * self.size))
        return value

    def value_range(self):
        """Range of the value in the register's own unit (what encode() accepts)."""
        if self.unit == "dir_speed":
            return (-0x7FFF, 0x7FFF)
        if self.unit == "temperature" and self.max > 0x7F:
            return (-0x7F, 0x7F)
        return (self.min, self.max)

    def _accepted(self):
        """What parse() accepts, for a refusal: ' (0..255, 500 us; or with a unit: 8ms)'."""
        lo, hi = self.value_range()
        factor, unit = self.scale()
        example = {"deg": "90deg", "deg/s": "45deg/s", "deg/s^2": "360deg/s^2",
                   "ms": "8ms", "A": "2.5A", "C": "60C"}.get(unit)
        return " (%d..%d%s%s)" % (lo, hi, ", " + UNIT_TEXT[self.unit]
                                   if self.unit in UNIT_TEXT else "",
                                   "; or with its unit, e.g. " + example if example else "")

    def _range_note(self):
        if self.unit == "dir_speed":
            return " (position units/s; the sign is bit 15, the direction)"
        if self.unit in UNIT_TEXT:
            return " (%s)" % UNIT_TEXT[self.unit]
        return ""

    # Value in the register's unit <-> physical quantity.

    def scale(self, resolution=10):
        """(factor, unit) turning the register's value into a physical quantity, or
        (None, '') for plain numbers. resolution is register 13 (0.1 deg units)."""
        deg = resolution * 0.1
        return {
            "position": (deg, "deg"),
            "speed": (deg, "deg/s"),
            "dir_speed": (deg, "deg/s"),
            "accel": (10.0, "deg/s^2"),
            "delay": (0.5, "ms"),
            "current": (0.1, "A"),
            "temperature": (1.0, "C"),
            "resolution": (0.1, "deg/unit"),
        }.get(self.unit, (None, ""))

    def format(self, value, resolution=10):
        """'90 (90.0 deg)' or '1' for a value in the register's unit."""
        factor, unit = self.scale(resolution)
        if factor is None:
            return str(value)
        phys = value * factor
        text = ("%.3f" % phys).rstrip("0").rstrip(".") if phys != int(phys) else "%d" % phys
        return "%d (%s %s)" % (value, text, unit)

    def parse(self, text, resolution=10):
        """The register's value from user text: an integer in the register's unit
        ('90', '-100', '0x20') or a physical quantity with its unit ('90deg', '45 deg/s',
        '8ms', '2.5A', '60C'), or a JSON number. Raises RangeError for what does not fit
        (values.py words it: empty, not a number, not a whole number, out of range)."""
        try:
            if isinstance(text, bool) or not isinstance(text, (str, int, float)):
                V.integer(text, self.name)  # the sentence for a value of the wrong type
            if isinstance(text, float):
                text = V.integer(text, self.name)  # 7.0 is 7; 7.9 is refused, not cut
        except RangeError as e:
            raise RangeError(str(e) + self._accepted()) from None
        text = str(text).strip()
        value = None
        for base in (0, 10):  # 0x20, 0b101; then 010 as decimal
            try:
                value = int(text, base)
                break
            except ValueError:
                pass
        m = None if value is not None else re.fullmatch(
            r"([-+]?(?:\d+\.?\d*|\.\d+))\s*([A-Za-z/^°2]+)", text)
        if m:
            number, unit = float(m.group(1)), m.group(2).replace("°", "deg").lower()
            factor, want = self.scale(resolution)
            aliases = {want.lower(), want.lower().replace("^", "")}
            if factor is None or unit not in aliases:
                raise RangeError("%s: unit '%s' does not fit; %s" % (
                    self.name, m.group(2),
                    "give a plain number" if factor is None else "use %s or a plain "
                    "number of %s" % (want, UNIT_TEXT[self.unit])))
            if not math.isfinite(number / factor):
                raise RangeError("%s: '%s' is out of range" % (self.name, text))
            value = round(number / factor)
        elif value is None:
            try:
                value = V.integer(text, self.name)  # 1e3, 7.0; or why not: empty, 7.9
            except RangeError as e:
                raise RangeError(str(e) + self._accepted()) from None
        self.encode(value)  # range check
        return value

    def __repr__(self):
        return "Register(%d, %s)" % (self.address, self.name)


REGISTERS = {}
BY_ADDRESS = {}
for _d in _DATA["registers"]:
    _r = Register(_d)
    REGISTERS[_r.name] = _r
    BY_ADDRESS[_r.address] = _r


def register(key):
    """A register by name ('goal_position', 'goal-position') or address (30, '30')."""
    if isinstance(key, Register):
        return key
    if isinstance(key, int) or (isinstance(key, str) and key.strip().isdigit()):
        address = int(key)
        if address in BY_ADDRESS:
            return BY_ADDRESS[address]
        raise UnknownRegister("no register starts at address %d (reserved or inside a "
                              "16-bit register); see `servoctl dump`" % address)
    name = str(key).strip().lower().replace("-", "_")
    if name in REGISTERS:
        return REGISTERS[name]
    close = [n for n in REGISTERS if name in n]
    raise UnknownRegister("no register named '%s'%s" % (
        key, "; did you mean %s?" % ", ".join(close) if close else
        "; `servoctl dump` lists them"))


def decode_table(data, first=0, variant=None):
    """{register name: value} of the registers wholly inside data (bytes READ from
    address `first`); None for a write-only register or one not on `variant`."""
    out = {}
    for r in REGISTERS.values():
        if first <= r.address and r.address + r.size <= first + len(data):
            if not r.readable or not r.applies_to(variant):
                out[r.name] = None
                continue
            off = r.address - first
            out[r.name] = r.decode(int.from_bytes(data[off:off + r.size], "little"))
    return out
