"""The studio's other actions: scan, select, a register write (lock-out settings
confirmed first, a clear of an unload retried), set ID, factory reset, firmware update,
clearing the log, and the state for a script. Each checks what it was given with
values.py before anything is queued (api.py answers for it)."""

import asyncio

from aiohttp import web

from .. import values as V
from ..protection import CLEAR_WINDOW_S, SAFETY_DRAIN_S
from ..registers import BAUD_RATES, register
from .api import Handler, ok
from .flows import do_scan, finish_update, start_update
from .jobs import Refused
from .words import sentence

# Writing these starts or changes a motion: a STOP cancels such a write while queued.
MOTION_REGISTERS = ("goal_position", "moving_speed", "homing")


class Actions(Handler):
    """POST /api/scan, select, write, setid, reset, update, clear; GET /api/state."""

    def add_routes(self, app):
        for path, fn in (("scan", self.scan), ("select", self.select),
                         ("write", self.write), ("setid", self.setid),
                         ("reset", self.reset), ("update", self.update),
                         ("clear", self.clear_log)):
            app.router.add_post("/api/" + path, fn)
        app.router.add_get("/api/state", self.state)

    async def state(self, _):
        """The shared state the page gets over the WebSocket, and the jobs queued or
        running (a script waits for 0 before it looks at the wire)."""
        return web.json_response(dict(self.st.state, jobs=len(self.st.queue) + (
            self.st.running is not None)))

    async def scan(self, request):
        async def go(body):
            V.fields(body, (), ("all", "baud"))
            every = V.flag(body.get("all", False), "all")
            baud = None
            if "baud" in body:
                baud = V.integer(body["baud"], "baud")
                if baud not in BAUD_RATES:
                    raise Refused("Baud %d is not one of %s. Nothing was sent." % (
                        baud, ", ".join(map(str, BAUD_RATES))), 400)
            self.not_busy()
            self.st.require_bus()  # a scan is never kept for when the bus comes back
            asyncio.ensure_future(do_scan(self.st, every, baud))
            return ok()
        return await self.handle(request, go)

    async def select(self, request):
        async def go(body):
            V.fields(body, ("id",))
            sid = V.servo_id(body["id"], "ID")
            self.not_busy()
            name = await self.st.call(self.st.select(sid))
            self.st.changed()
            return ok(variant=name)
        return await self.handle(request, go)

    async def write(self, request):
        async def go(body):
            V.fields(body, ("name", "value"), ("id", "confirm"))
            confirm = V.flag(body.get("confirm", False), "confirm")
            sid = self.target(body)
            self.not_busy()
            reg, value = self._register_value(body, sid)
            if reg.name == "clear_unload" and value == 1:
                return await self._clear(sid)
            if not confirm:
                reasons = await self.st.call(lambda bus: bus.lockout(sid, {reg.name: value}))
                if reasons:
                    raise Refused("%s Confirm to write it anyway. Nothing was written." %
                                  sentence(reasons[0]), 409, confirm=sentence(reasons[0]))
            now = await self.st.call(self._write_job(sid, reg, value), "ID %d: WRITE %s = %s"
                                     % (sid, reg.name, value),
                                     motion=reg.name in MOTION_REGISTERS)
            self.st.table_due = 0.0
            return ok(value=now)
        return await self.handle(request, go)

    def _register_value(self, body, sid):
        """(register, value in its unit) from the body; 400 for what does not fit."""
        if isinstance(body["name"], bool) or not isinstance(body["name"], (str, int)):
            raise Refused("'name' must be a register's name or address. Nothing was "
                          "sent.", 400)
        reg = register(body["name"])
        if not reg.writable:
            raise Refused("%s is read-only. Nothing was sent." % reg.name, 400)
        if reg.name == "id":
            raise Refused("Change the ID in the ID & reset panel: it checks that the new "
                          "ID is free first. Nothing was sent.", 400)
        variant = self.st.variant if sid == self.st.selected else None
        if not reg.applies_to(variant):
            raise Refused("%s does not exist on the %s. Nothing was sent." % (
                reg.name, variant.name), 400)
        return reg, reg.parse(body["value"], self.st.resolution)

    def _write_job(self, sid, reg, value):
        st = self.st

        def job(bus):
            bus.write(sid, reg.name, value)
            if reg.name == "baud_rate":  # it answers at its new baud from now on
                st.follow_baud(bus, sid, value)
            if reg.name == "angle_resolution":  # degrees mean other units from now on
                st.set_resolution(sid, value)
            if not reg.readable or (reg.name == "status_return_level" and value == 0):
                return value  # at level 0 it answers nothing but PING: no read-back
            return bus.read(sid, reg.name)
        return job

    async def _clear(self, sid):
        """clear_unload 1, retried while the servo still sees the cause (up to
        CLEAR_WINDOW_S: its drain time is SAFETY_DRAIN_S), and what it took said."""
        took = await self.st.call(lambda bus: bus.clear_unload(sid), "ID %d: clear unload "
                                  "(register 25), retried for up to %.1f s while the servo "
                                  "still sees the cause" % (sid, CLEAR_WINDOW_S))
        self.st.table_due = 0.0
        return ok(value=1, took=round(took, 1), drain=SAFETY_DRAIN_S)

    async def setid(self, request):
        async def go(body):
            V.fields(body, ("new_id",), ("id",))
            new = V.servo_id(body["new_id"], "new ID")
            sid = self.target(body)
            self.not_busy()
            if new == sid:
                raise Refused("ID %d is its ID already. Nothing was sent." % new, 400)
            taken = [s for s in self.st.state["servos"] if s["id"] == new]
            if taken:
                raise Refused("ID %d is taken by the %s on this bus: choose another ID. "
                              "Nothing was sent." % (new, taken[0]["variant"]), 409)
            # Bus.set_id PINGs the new ID at every baud the port reaches first
            await self.st.call(lambda bus: bus.set_id(sid, new), "ID %d: set ID to %d" % (
                sid, new))
            self.st.renumbered(sid, new)
            await self.st.call(self.st.select(new))
            self.st.changed()
            return ok(id=new)
        return await self.handle(request, go)

    async def reset(self, request):
        async def go(body):
            V.fields(body, ("yes",), ("id",))
            if not V.flag(body["yes"], "yes"):
                raise Refused("A factory reset needs yes: true. Nothing was sent.", 400)
            sid = self.target(body)
            self.not_busy()
            await self.st.call(lambda bus: bus.reset(sid), "ID %d: factory reset" % sid)
            self.st.selected = None
            self.st.changed()
            asyncio.ensure_future(do_scan(self.st, False))
            return ok()
        return await self.handle(request, go)

    async def update(self, request):
        async def go(_):
            query = dict(request.query)
            V.fields(query, ("id",), ("file",))
            sid = V.servo_id(query["id"], "ID")
            self.not_busy()
            data = await request.read()
            if not data:
                raise Refused("Choose a firmware file first. Nothing was sent.", 400)
            future = start_update(self.st, sid, data, query.get("file", "the image"))
            asyncio.ensure_future(finish_update(self.st, sid, future))
            return ok()
        return await self.handle(request, go, read_body=False)

    async def clear_log(self, request):
        async def go(body):
            V.fields(body)
            self.st.state["log"] = []
            self.st.changed()
            return ok()
        return await self.handle(request, go)

