"""The studio's sentences: an exception in words for the page, and the control table as
the page shows it."""

import re

from .. import BusTimeout, Interrupted, ServoBusError
from ..registers import REGISTERS, UNIT_TEXT


def is_link_error(e):
    """The connection to the bus itself failed (as opposed to one servo's answer)."""
    if isinstance(e, OSError):
        return True
    return type(e) is ServoBusError and bool(re.search(
        r"connect|closed the connection|cannot open|lost the", str(e)))


def sentence(text):
    """text as a sentence: a capital first, a full stop last."""
    text = " ".join(str(text).split())
    first = text.split(" ", 1)[0].rstrip(":,")
    if first.isalpha() and first.islower() and first not in REGISTERS:  # id stays id
        text = text[0].upper() + text[1:]
    return text if text.endswith((".", "!", "?")) else text + "."


def in_words(e, baud=None):
    """An exception as a sentence for the page."""
    text = str(e)
    if isinstance(e, BusTimeout) and e.update_mode:
        return sentence("%s — recover it in the Firmware panel" % text)
    if isinstance(e, BusTimeout):
        sid = getattr(e, "servo_id", None)
        who = "ID %d" % sid if sid is not None else "the servo"
        return sentence("No answer from %s%s: no servo with that ID, the wrong baud rate, "
                        "or power and wiring (%s)" % (who, " at %d baud" % baud if baud
                                                      else "", text))
    if isinstance(e, Interrupted) and e.written:  # settings half written: say which
        return ("Stopped by STOP part way: %s written; %s not written (do it again to "
                "finish; nothing more of it was sent)." % (
                    ", ".join("%s = %s" % kv for kv in e.written.items()),
                    ", ".join(e.unwritten) or "nothing else"))
    if isinstance(e, Interrupted):
        return "Stopped by STOP before it was done: nothing more of it was sent."
    if is_link_error(e):
        if "closed the connection" in text:
            return ("Bus busy: the port %s — another program is connected to it." %
                    text.split(" closed")[0])
        return sentence("The bus is gone: %s" % text)
    return sentence(text)


def register_info():
    """The control table for the page (from registers.json via the registers module)."""
    out = []
    for r in REGISTERS.values():
        lo, hi = r.value_range()
        out.append({
            "address": r.address, "name": r.name, "size": r.size, "access": r.access,
            "area": r.area, "variants": list(r.variants), "min": lo, "max": hi,
            "unit": r.unit or "", "unit_text": UNIT_TEXT.get(r.unit, ""), "doc": r.doc,
            "default": r.default,
        })
    return out
