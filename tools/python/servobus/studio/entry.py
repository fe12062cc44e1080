"""The wire console's entry line (issue 29): a frame in hex (the checksum filled in) or a
servoctl command, through the same checks as every form before anything is sent —
servobus/values.py and Register ranges, the servo's variant, CW <= CCW (Bus.plan_write),
the lock-out rules with the page's confirmation (Bus.lockout), the ID and the firmware
left to their panels (which check a new ID is free, and the image) — and the answer
shown decoded (the console's record of what came back)."""

import contextlib
import io
import re
import shlex

from .. import frames as F
from .. import protocol as P
from .. import values as V
from ..cli.args import build_parser
from ..cli.common import UsageError
from ..errors import RangeError, ServoBusError
from ..registers import REGISTERS
from .actions import MOTION_REGISTERS
from .api import Handler, ok
from .jobs import Refused
from .words import in_words, sentence

COMMANDS = ("ping", "get", "set", "dump", "move", "speed", "stop", "home", "traj")
_MOTION_INS = (P.ACTION, P.TRAJ_ACTION, P.START_END, P.CUSTOM)
_STATIC_LOCKOUT = {"status_return_level": lambda v: v == 0, "baud_rate": lambda v: True}


# servoctl's commands that the console does not run, and where the studio does them
ELSEWHERE = {
    "studio": "this is the studio (one per bus)",
    "update": "use the Firmware panel, which checks the whole image first",
    "set-id": "use the ID & reset panel, which checks that the new ID is free first",
    "reset": "use the ID & reset panel, which asks first (or send the RESET frame in hex, "
             "which asks too)",
    "config": "use the Configuration files panel (save, restore, diff)",
    "scan": "use the Scan panel (Scan again, or every baud)",
    "monitor": "use the Live plot, Plot any register or All servos (the studio reads "
               "the servos all the time)",
}
# servoctl's options that take a value (before or after the command)
_VALUED = ("--port", "--baud", "--id", "--timeout")


def _command_word(words):
    """The command of a servoctl command line (its first word that is neither an option
    nor an option's value), or None."""
    skip = False
    for w in words:
        if skip:
            skip = False
        elif w.startswith("-"):
            skip = w in _VALUED
        else:
            return w
    return None


def _whole_registers(sid, fields):
    """{name: value} of a WRITE's data; 400 for bytes that are not whole registers."""
    named = {}
    for name, value, _ in fields:
        if name.startswith("byte") or not REGISTERS[name].writable:
            raise Refused("ID %s: %s is not a writable register (the data must cover whole "
                          "writable registers). Nothing was sent." % (sid, name), 400)
        named[name] = value
    if "id" in named:
        raise Refused("Change an ID in the ID & reset panel (or `set-id`): it checks that "
                      "the new ID is free first. Nothing was sent.", 400)
    return named


class Entry(Handler):
    """POST /api/console {"text": hex or servoctl command, "confirm": bool};
    GET /api/frames (the record for a tab opened later)."""

    def add_routes(self, app):
        app.router.add_post("/api/console", self.console)
        app.router.add_get("/api/frames", self.frames)

    async def frames(self, _):
        return ok(frames=self.st.recorder.recent())

    async def console(self, request):
        async def go(body):
            V.fields(body, ("text",), ("confirm",))
            confirm = V.flag(body.get("confirm", False), "confirm")
            text = body["text"]
            if not isinstance(text, str) or not text.strip():
                raise Refused("Type a frame in hex (D5 5D 01 04 02 24 02) or a servoctl "
                              "command (get present_position). Nothing was sent.", 400)
            self.not_busy()
            if F.looks_like_hex(text):
                return await self._frame(text, confirm)
            return await self._command(text, confirm)
        return await self.handle(request, go)

    # ---- a frame in hex -------------------------------------------------------------

    async def _frame(self, text, confirm):
        raw = F.parse_hex(text)
        sid, ins, params = raw[2], raw[4], raw[5:-1]
        if ins not in P.INSTRUCTION_NAMES:
            raise Refused("Instruction 0x%02X is not one of the protocol's (§4). Nothing "
                          "was sent." % ins, 400)
        if ins == P.CUSTOM and params[:1] in (bytes([P.UPDATE_ENTER]), bytes([P.UPDATE_BLOCK])):
            raise Refused("Firmware update frames go through the Firmware panel: it checks "
                          "the whole image first. Nothing was sent.", 400)
        if ins == P.RESET and not confirm:
            raise Refused("RESET puts every setting of ID %d back to its factory value (ID 1, "
                          "the default baud). Confirm to send it. Nothing was sent." % sid,
                          409, confirm="RESET: every setting of ID %d goes back to its "
                          "factory value (ID 1, the default baud)." % sid)
        named = await self._check_writes(sid, ins, params, confirm)
        per_id = self._sync_resolutions(sid, ins, params)
        motion = ins in _MOTION_INS or any(n in MOTION_REGISTERS for n in named)
        rec, st = self.st.recorder, self.st

        def job(bus):
            first = rec.mark()
            try:
                if sid == P.BROADCAST and ins == P.PING:
                    bus.scan()  # the same broadcast PING, its ID slots listened to
                else:
                    if ins == P.REG_WRITE:  # held: a group move's ACTION replaces it
                        st.held.update(s["id"] for s in st.state["servos"]) if \
                            sid == P.BROADCAST else st.held.add(sid)
                    bus.transact(sid, ins, params, nbytes=params[1] + 6 if ins == P.READ
                                 and len(params) == 2 else 7, motion=ins in _MOTION_INS)
                    if ins == P.ACTION:
                        st.held.clear() if sid == P.BROADCAST else st.held.discard(sid)
                    if "angle_resolution" in named and ins == P.WRITE:
                        for i in ([s["id"] for s in st.state["servos"]]
                                  if sid == P.BROADCAST else [sid]):
                            st.set_resolution(i, named["angle_resolution"])
                    for i, value in per_id.items():  # a SYNC WRITE of register 13
                        st.set_resolution(i, value)
            except ServoBusError as e:
                return first, rec.mark(), in_words(e, bus.baud)
            return first, rec.mark(), ""
        what = "console: %s" % F.decode_instruction(raw)["name"]
        first, last, error = await self.st.call(
            job, "%s to ID %d (%s)" % (what, sid, raw.hex(" ")), motion=motion)
        return ok(frames=rec.between(first, last), error=error)

    @staticmethod
    def _sync_resolutions(sid, ins, params):
        """{ID: angle resolution} a SYNC WRITE sets (the studio's degrees follow it)."""
        if ins != P.SYNC_WRITE:
            return {}
        d = F.decode_instruction(P.instruction(sid, ins, params))
        return {int(name[3:].split(": ", 1)[0]): value for name, value, _ in d["fields"]
                if name.endswith(": angle_resolution")}

    async def _check_writes(self, sid, ins, params, confirm):
        """The registers a WRITE, REG WRITE or SYNC WRITE carries, checked as a form's
        values are: whole writable registers, ranges, variant, CW <= CCW, lock-out."""
        if ins == P.SYNC_WRITE:
            d = F.decode_instruction(P.instruction(sid, ins, params))
            per = {}
            for name, value, _ in d["fields"]:
                i, reg = name[3:].split(": ", 1)
                per.setdefault(int(i), []).append((reg, value, ""))
            for i, fields in per.items():
                await self._check_one(i, _whole_registers(i, fields), confirm)
            return {n: v for fields in per.values() for n, v, _ in fields}
        if ins not in (P.WRITE, P.REG_WRITE) or not params:
            return {}
        named = _whole_registers(sid, F.registers_in(params[0], params[1:]))
        await self._check_one(sid, named, confirm)
        return named

    async def _check_one(self, sid, named, confirm):
        if not named:
            raise Refused("The write carries no register. Nothing was sent.", 400)
        if sid == P.BROADCAST:  # every servo: the rules that need no answer
            for n, v in named.items():
                REGISTERS[n].encode(v)
            reasons = ["%s %d to every servo: the ones that take it may stop answering "
                       "this studio" % (n, v) for n, v in named.items()
                       if n in _STATIC_LOCKOUT and _STATIC_LOCKOUT[n](v)]
        else:
            rest = {n: v for n, v in named.items() if n != "clear_unload"}
            if rest:
                await self.st.call(lambda bus: bus.plan_write(sid, rest))
            reasons = await self.st.call(lambda bus: bus.lockout(sid, named))
        if reasons and not confirm:
            raise Refused("%s Confirm to send it anyway. Nothing was sent." %
                          sentence(reasons[0]), 409, confirm=sentence(reasons[0]))

    # ---- a servoctl command ---------------------------------------------------------

    async def _command(self, text, confirm):
        try:
            words = shlex.split(text)
        except ValueError as e:
            raise Refused("The command does not parse: %s. Nothing was sent." % e, 400) \
                from None
        words = words[1:] if words and words[0] == "servoctl" else words
        refused = [w for w in words if re.match(r"--(port|baud|force|yes)\b", w)]
        if refused:
            raise Refused("%s: the console talks on the studio's own bus, and asks before "
                          "a setting that locks a servo out (no --force). Nothing was "
                          "sent." % refused[0], 400)
        waits = [w for w in words if re.match(r"--wait\b", w)]
        if waits:
            raise Refused("%s: the console does not hold the bus while a servo moves (the "
                          "studio's other actions and its live values would wait behind "
                          "it); the studio keeps reading the servo: watch the Live plot "
                          "or All servos. Nothing was sent." % waits[0], 400)
        command = _command_word(words)
        if command in ELSEWHERE:
            raise Refused("`%s` is not taken in the console: %s. Nothing was sent." % (
                command, ELSEWHERE[command]), 400)
        if command is not None and command not in COMMANDS and \
                not any(w in ("-h", "--help") for w in words):
            raise Refused("'%s' is neither a command the console takes (%s) nor a frame in "
                          "hex (D5 5D 02 04 02 24 02). Nothing was sent." % (
                              command, ", ".join(COMMANDS)), 400)
        err, out = io.StringIO(), io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            try:
                args = build_parser().parse_args(words)
            except SystemExit as e:
                if e.code == 0 and out.getvalue():  # -h: the help, nothing sent
                    return ok(output=out.getvalue(), frames=[])
                args = None
        if args is None or args.command not in COMMANDS:
            why = err.getvalue().strip().splitlines()
            raise Refused("%s. The console takes %s. Nothing was sent." % (
                why[-1] if why else "not a command", ", ".join(COMMANDS)), 400)
        args.id = getattr(args, "id", 1)
        args.force = False
        if args.command == "set":
            await self._check_set(args, confirm)
        rec = self.st.recorder

        def job(bus):
            first = rec.mark()
            out = self._run(bus, args)
            if "angle_resolution" in getattr(args, "written", {}):
                self.st.set_resolution(args.id, args.written["angle_resolution"])
            return first, out, rec.mark()
        first, out, last = await self.st.call(job, "console: servoctl " + " ".join(words),
                                              motion=args.command in ("move", "speed",
                                                                      "home", "traj"))
        return ok(output=out, frames=rec.between(first, last))

    async def _check_set(self, args, confirm):
        from ..cli.table import _parse_pairs

        def check(bus):
            values, _ = _parse_pairs(bus, args)
            if "id" in values:
                raise Refused("Change an ID in the ID & reset panel (or `set-id`): it "
                              "checks that the new ID is free first. Nothing was sent.", 400)
            rest = {k: v for k, v in values.items() if k != "clear_unload"}
            if rest:
                bus.plan_write(args.id, rest)
            args.written = values  # what the set writes (the studio's degrees follow)
            return bus.lockout(args.id, values)
        reasons = await self.st.call(check)
        if reasons and not confirm:
            raise Refused("%s Confirm to write it anyway. Nothing was written." %
                          sentence(reasons[0]), 409, confirm=sentence(reasons[0]))
        args.force = bool(reasons)  # confirmed: servoctl's --force, for these only

    @staticmethod
    def _run(bus, args):
        """Run the servoctl command on the studio's Bus; what it printed."""
        out = io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
            try:
                args.func(bus, args)
            except (UsageError, RangeError) as e:
                raise Refused("%s. Nothing more was sent." % e, 400) from None
        return out.getvalue()
