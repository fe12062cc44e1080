"""How the studio answers a JSON action (/api/*): the body read and checked, the
refusals mapped to HTTP statuses, every answer JSON.

    {"ok": true, ...}                              200
    {"ok": false, "error": sentence, "sent": bool}  4xx, never 5xx for what was given

400: what was given is wrong (values.py says why), nothing sent. 413: more than 1 MiB,
nothing sent. 403: not the studio's
page (security.py). 409: not now (busy, no servo selected, the bus gone, a setting
that needs confirming, cancelled by STOP), nothing sent. 422: sent, and the bus or a
servo said no (a time-out, a refusal)."""

import json

from aiohttp import web

from .. import IdTaken, ImageError, Interrupted, RangeError, ServoBusError, UnknownRegister
from .. import values as V
from .jobs import Refused
from .words import in_words, sentence


def ok(**kw):
    return web.json_response(dict(ok=True, **kw))


def refused(text, status, sent=False, **extra):
    return web.json_response(dict(ok=False, error=text, sent=sent, **extra), status=status)


async def json_body(request):
    """The request's JSON object (400 for a body that is not JSON at all)."""
    raw = await request.read()
    if not raw.strip():
        return {}
    try:
        return json.loads(raw.decode("utf-8"), parse_constant=_no_constant)
    except (ValueError, UnicodeDecodeError):
        raise Refused("The request is not JSON. Nothing was sent.", 400) from None


def _no_constant(name):
    # NaN and Infinity are not JSON, whatever Python's json module would make of them
    raise ValueError("%s is not JSON" % name)


class Handler:
    """The frame every action runs in: fn(body) on the shared Studio st."""

    def __init__(self, st):
        self.st = st

    async def handle(self, request, fn, read_body=True):
        """Run fn(body) and answer for it: what it returns (a Response), or the
        refusal its exception stands for (logged, for the page's log)."""
        try:
            body = await json_body(request) if read_body else None
            return await fn(body)
        except Exception as e:  # noqa: BLE001 (every refusal is answered in words)
            text, status, sent, extra = self._refusal(e)
        if not extra.get("confirm"):
            self.st.log("refused: %s" % text, ok=False)
        return refused(text, status, sent, **extra)

    def _refusal(self, e):
        """(sentence, HTTP status, sent, extra fields) for an exception; anything
        that is not a refusal is raised again (a bug: the server answers 500)."""
        if isinstance(e, Refused):
            return sentence(e), e.status, e.sent, e.extra
        if isinstance(e, web.HTTPRequestEntityTooLarge):  # aiohttp's words are no sentence
            return ("This is more than the studio takes in one request (1 MiB): a "
                    "firmware image is the stamped .bin of tools/fwstamp.py (tens of "
                    "KiB, not the .elf), a configuration file a few hundred bytes. "
                    "Nothing was sent."), 413, False, {}
        if isinstance(e, (RangeError, UnknownRegister, ImageError)):
            return sentence(e) + " Nothing was sent.", 400, False, {}
        if isinstance(e, IdTaken):
            return sentence(e) + " Nothing was sent.", 409, False, {}
        if isinstance(e, Interrupted):
            return in_words(e), 409, True, {}
        if isinstance(e, (ServoBusError, OSError)):
            st = self.st
            return in_words(e, st.bus.baud if st.bus else None), 422, True, {}
        raise e

    # ---- what every servo action checks --------------------------------------------

    def target(self, body):
        """The servo an action is for: body's id, or the selected servo (409 if none)."""
        if "id" in body:
            return V.servo_id(body["id"], "ID")
        if self.st.selected is None:
            raise Refused("No servo selected: scan, then pick one in the list. Nothing "
                          "was sent.", 409)
        return self.st.selected

    def not_busy(self):
        if self.st.busy:
            raise Refused("The bus is busy: %s. Try again when it is done (STOP is never "
                          "refused). Nothing was sent." % self.st.busy, 409)

    def res(self, sid):
        """Servo sid's angle resolution as the studio knows it (0.1 deg units)."""
        return self.st.resolution if sid == self.st.selected else \
            self.st.resolutions.get(sid, 10)

    def units(self, deg, what, lo, hi, unit="deg", sid=None):
        """Degrees (or deg/s) given by the page, in position units at servo sid's
        resolution (default: the selected servo's): a number within lo..hi (in
        degrees), else 400."""
        deg = V.number(deg, what, lo, hi, unit)
        res = self.st.resolution if sid is None else self.res(sid)
        return int(round(deg / (res * 0.1)))
