"""The studio's identities (issue 27): every servo by its unique ID (UID), duplicates
marked, *Separate* (each shared ID: the lowest UID keeps it, the others take free IDs)
and *Adopt* (a replacement takes the one silent expected ID and the bus's baud). The
same SDK calls as `servoctl ids --fix` and `servoctl adopt` (servobus/ids.py), and the
same memory of which UID had which ID on each port (known-uids.json, written by a list
of a bus in order, by either), so a replacement beside the old servo on one ID is told
apart here too; every value checked with values.py before anything is sent."""

import asyncio
import collections

from .. import values as V
from ..cli.ids import load_known, save_known
from ..ids import uid_text
from .api import Handler, ok
from .flows import do_scan
from .jobs import Refused


def _rows(idents):
    count = collections.Counter(i.id for i in idents)
    return [{"uid": uid_text(i.uid), "id": i.id, "variant": i.variant, "model": i.model,
             "baud": i.baud, "duplicate": count[i.id] > 1} for i in idents]


class IdActions(Handler):
    """POST /api/ids (list by UID), /api/separate, /api/adopt {expect: [IDs]}."""

    def add_routes(self, app):
        for path, fn in (("ids", self.ids), ("separate", self.separate),
                         ("adopt", self.adopt)):
            app.router.add_post("/api/" + path, fn)

    def _show(self, idents, message):
        shared = sorted({r["id"] for r in _rows(idents) if r["duplicate"]})
        self.st.state["ids"] = {"rows": _rows(idents), "shared": shared, "message": message}
        self.st.changed()

    async def ids(self, request):
        async def go(body):
            V.fields(body)
            self.not_busy()
            def job(bus):
                idents = bus.enumerate()
                save_known(bus.port, idents)  # as servoctl ids: adopt tells old from new
                return idents
            found = await self.st.call(job, "ENUMERATE: every servo by UID")
            shared = sorted({i.id for i in found if sum(j.id == i.id for j in found) > 1})
            self._show(found, "%d servo%s by UID%s." % (
                len(found), "" if len(found) == 1 else "s",
                ": ID %s shared — Separate gives each a free ID" % ", ".join(map(str, shared))
                if shared else ", every ID single"))
            return ok(count=len(found), shared=shared)
        return await self.handle(request, go)

    async def separate(self, request):
        async def go(body):
            V.fields(body)
            self.not_busy()

            def job(bus):
                moves = bus.fix_duplicates()
                return moves, bus.enumerate()
            moves, now = await self.st.call(job, "Separate: a free ID for every servo "
                                            "that shares one (by UID)")
            for uid, old, new in moves:
                self.st.log("UID %s: ID %d -> %d" % (uid_text(uid), old, new))
            self._show(now, "Separated: %s." % (", ".join(
                "UID %s ID %d \u2192 %d" % (uid_text(u), o, n) for u, o, n in moves)
                if moves else "nothing to do, every ID was single"))
            asyncio.ensure_future(do_scan(self.st, False))
            return ok(moves=[[uid_text(u), o, n] for u, o, n in moves])
        return await self.handle(request, go)

    async def adopt(self, request):
        async def go(body):
            V.fields(body, ("expect",))
            expect = body["expect"]
            if not isinstance(expect, list) or not expect:
                raise Refused("Give the expected IDs, e.g. 1, 2, 3, 4. Nothing was sent.", 400)
            expect = [V.servo_id(e, "expected ID") for e in expect]
            self.not_busy()

            def job(bus):
                uid, new = bus.adopt(expect, known=load_known(bus.port))
                now = bus.enumerate()
                save_known(bus.port, now)
                return uid, new, now
            uid, new, now = await self.st.call(job, "Adopt: the new servo takes the silent "
                                               "ID of %s" % ", ".join(map(str, expect)))
            self.st.log("adopt: UID %s is now ID %d" % (uid_text(uid), new))
            self._show(now, "Adopted: UID %s is now ID %d." % (uid_text(uid), new))
            asyncio.ensure_future(do_scan(self.st, False))
            return ok(uid=uid_text(uid), id=new)
        return await self.handle(request, go)
