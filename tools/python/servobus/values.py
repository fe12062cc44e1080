"""The one validator for values a user gives: the SDK's arguments, servoctl's command
line and Servo Studio's forms all go through these rules, so a value is accepted or
refused the same way everywhere, with the same sentence, before anything is sent.

Two kinds of input:
- Python values given to the SDK (`strict`): an int is an int; a string, a float or a
  bool where an integer is meant is refused.
- What a person typed or a page posted (text from a command line or a form, numbers and
  strings from JSON): '7', 7 and 7.0 are the integer 7; '', 'abc', 'nan', 'inf', '1e400',
  true, null, lists and objects are not numbers; 7.9 is not an integer.

Every refusal is a RangeError (a ServoBusError and a ValueError) whose message says
which value, what was given and what is accepted."""

import math

from .errors import RangeError

ID_MAX = 253
BROADCAST = 254


def _shown(value):
    """How a refused value is quoted back: text as typed, anything else as JSON would."""
    if isinstance(value, str):
        return "'%s'" % value if value.strip() else "an empty value"
    if value is None:
        return "nothing (null)"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple, set, frozenset)):
        return "a list"
    if isinstance(value, (bytes, bytearray, memoryview)):
        return "bytes"
    if isinstance(value, dict):
        return "an object"
    return repr(value)


def _span(lo, hi, unit):
    text = "%s..%s" % (_g(lo), _g(hi))
    return text + (" " + unit if unit else "")


def _g(x):
    """A number as a person writes it: 7, 7.5, 1e+30."""
    return ("%d" % x) if abs(x) < 1e15 and float(x).is_integer() else ("%g" % x)


def _to_float(value, what, want):
    """A finite number from a JSON number or text; want says what is accepted."""
    if isinstance(value, str) and not value.strip():
        raise RangeError("%s is empty: give %s" % (what, want))
    x = None
    if isinstance(value, str):
        try:
            x = float(value.strip())
        except ValueError:
            pass
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        x = value
    if x is None or not math.isfinite(x):
        raise RangeError("%s: %s is not a number; give %s" % (what, _shown(value), want))
    return x


def number(value, what, lo=None, hi=None, unit=""):
    """A finite number from user input (JSON number or text), within lo..hi."""
    want = "a number" + (" %s" % _span(lo, hi, unit) if lo is not None else "")
    x = _to_float(value, what, want)
    if lo is not None and not lo <= x <= hi:
        raise RangeError("%s: %s is out of range %s" % (what, _g(x), _span(lo, hi, unit)))
    return x


def integer(value, what, lo=None, hi=None, unit=""):
    """A whole number from user input: 7, 7.0 and '7' are 7; 7.9 is refused, never cut
    to 7. Text may also be hexadecimal ('0x20')."""
    want = "a whole number" + (" %s" % _span(lo, hi, unit) if lo is not None else "")
    if isinstance(value, str) and value.strip().lower().lstrip("+-").startswith("0x"):
        try:
            value = int(value.strip(), 16)
        except ValueError:
            raise RangeError("%s: %s is not a number; give %s" % (
                what, _shown(value), want)) from None
    x = _to_float(value, what, want)
    if isinstance(x, float):
        if not x.is_integer():
            raise RangeError("%s: %s is not a whole number%s" % (
                what, _g(x), "; give %s" % _span(lo, hi, unit) if lo is not None else ""))
        x = int(x)
    if lo is not None and not lo <= x <= hi:
        raise RangeError("%s: %s is out of range %s" % (what, _g(x), _span(lo, hi, unit)))
    return x


def strict_integer(value, what, lo=None, hi=None, unit=""):
    """An int given to the SDK (not a bool, a float or text), within lo..hi."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise RangeError("%s: %s is not an integer" % (what, _shown(value)))
    if lo is not None and not lo <= value <= hi:
        raise RangeError("%s: %s is out of range %s" % (what, _g(value), _span(lo, hi, unit)))
    return value


def flag(value, what):
    """true or false, and nothing else: 'no', 0 and 'false' are not a yes/no answer."""
    if not isinstance(value, bool):
        raise RangeError("%s: %s is not true or false" % (what, _shown(value)))
    return value


def servo_id(value, what="ID", broadcast=False, strict=False):
    """A servo's ID, 0-253 (or 254, broadcast, where allowed)."""
    top = BROADCAST if broadcast else ID_MAX
    check = strict_integer if strict else integer
    x = check(value, what, None, None)
    if x == BROADCAST and not broadcast:
        raise RangeError("ID 254 is the broadcast ID: nobody answers it (except a "
                         "broadcast PING, which scan() sends); give one servo's ID 0-253")
    if not 0 <= x <= top:
        raise RangeError("ID %d is not a servo ID (0-253%s)" % (
            x, ", or 254 to broadcast" if broadcast else ""))
    return x


def fields(body, required=(), optional=()):
    """A request's fields: body must be an object with every required key and no key
    that is neither required nor optional."""
    if not isinstance(body, dict):
        raise RangeError("the request is %s, not an object of fields" % _shown(body))
    missing = [k for k in required if k not in body]
    if missing:
        named = ["'%s'" % k for k in missing]
        raise RangeError("%s %s missing" % (
            named[0] if len(named) == 1 else ", ".join(named[:-1]) + " and " + named[-1],
            "is" if len(named) == 1 else "are"))
    unknown = sorted(k for k in body if k not in required and k not in optional)
    if unknown:
        raise RangeError("unexpected field%s %s" % (
            "" if len(unknown) == 1 else "s", ", ".join("'%s'" % k for k in unknown)))
    return body


def data(value, what):
    """Bytes given to the SDK: bytes, bytearray or memoryview (not text, not a number)."""
    if not isinstance(value, (bytes, bytearray, memoryview)):
        raise RangeError("%s: %s is not bytes" % (what, _shown(value)))
    return bytes(value)


def mapping(value, what):
    """A dict given to the SDK ({register: value, ...})."""
    if not isinstance(value, dict):
        raise RangeError("%s: %s is not a dict of {register: value}" % (what, _shown(value)))
    return value


def names(value, what):
    """A list (or tuple, set) of register names or addresses given to the SDK."""
    if isinstance(value, (str, bytes, dict)) or not isinstance(value, (list, tuple, set,
                                                                     frozenset)):
        raise RangeError("%s: %s is not a list of registers" % (what, _shown(value)))
    if not value:
        raise RangeError("%s: no register given" % what)
    return list(value)


def seconds(value, what, lo, hi):
    """A duration in seconds given to the SDK: an int or a float, finite, lo..hi."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(value) or not lo <= value <= hi:
        raise RangeError("%s: %s is not a number of seconds %s" % (
            what, _shown(value), _span(lo, hi, "")))
    return value
