"""The expert panels' actions (issue 29): the dashboard's polling and its group move,
the plot of any register, the trajectory editor's planned profile, and configuration
files. Every value goes through values.py (and the SDK's checks) before anything is
queued; a restore asks before a setting that locks a servo out, as a form does."""

from .. import config as C
from .. import planner
from .. import protocol as P
from .. import values as V
from ..registers import REGISTERS, register, variant_by_model
from .. import Interrupted, ServoBusError
from .api import Handler, ok
from .jobs import Refused
from .words import is_link_error, sentence

MAX_TRACES = 12


class Panels(Handler):
    """POST /api/dashboard, /api/scope, /api/group, /api/plan, /api/config/{save,
    restore,diff}."""

    def add_routes(self, app):
        for path, fn in (("dashboard", self.dashboard), ("scope", self.scope),
                         ("group", self.group), ("plan", self.plan),
                         ("config/save", self.config_save),
                         ("config/restore", self.config_restore),
                         ("config/diff", self.config_diff)):
            app.router.add_post("/api/" + path, fn)

    def _entry(self, sid):
        entry = next((s for s in self.st.state["servos"] if s["id"] == sid), None)
        if entry is None:
            raise Refused("ID %d is not in the last scan: scan first. Nothing was sent." %
                          sid, 409)
        return entry

    async def dashboard(self, request):
        async def go(body):
            V.fields(body, ("on",), ("tab",))
            on = V.flag(body["on"], "on")
            self.st.live.set_dash(_tab(body), on)
            self.st.wake()
            return ok(on=on, polling=self.st.live.dash_on)
        return await self.handle(request, go)

    async def scope(self, request):
        async def go(body):
            V.fields(body, ("picks",), ("tab",))
            tab = _tab(body)
            if not isinstance(body["picks"], list) or len(body["picks"]) > MAX_TRACES:
                raise Refused("'picks' must be a list of at most %d {id, register}. "
                              "Nothing was sent." % MAX_TRACES, 400)
            picks = {}
            for p in body["picks"]:
                if not isinstance(p, dict):
                    raise Refused("Each pick is {\"id\": N, \"register\": name}. Nothing "
                                  "was sent.", 400)
                V.fields(p, ("id", "register"))
                sid = V.servo_id(p["id"], "ID")
                r = register(p["register"])
                if not r.readable:
                    raise Refused("%s cannot be read (write-only). Nothing was sent." %
                                  r.name, 400)
                variant = variant_by_model(self._entry(sid)["model"])
                if not r.applies_to(variant):
                    raise Refused("%s does not exist on ID %d (the %s). Nothing was sent." % (
                        r.name, sid, variant.name), 400)
                picks.setdefault(sid, []).append(r.name)
            reads = self.st.live.set_picks(tab, picks, self.st.state["baud"])
            self.st.wake()
            return ok(reads=[[sid, a, n] for sid, a, n, _ in reads])
        return await self.handle(request, go)

    async def group(self, request):
        """Several servos to one goal each, together: REG WRITE to each (answered, so a
        refusal is seen before anything moves) then one broadcast ACTION, or one SYNC
        WRITE (how: "sync"). STOP stops them all (the broadcast of every STOP)."""
        async def go(body):
            V.fields(body, ("goals", "speed"), ("how",))
            how = body.get("how", "action")
            if how not in ("action", "sync"):
                raise Refused("'how' is \"action\" (REG WRITE, then one ACTION) or \"sync\" "
                              "(one SYNC WRITE). Nothing was sent.", 400)
            if not isinstance(body["goals"], dict) or not 2 <= len(body["goals"]) <= 50:
                raise Refused("Pick at least two servos (goals: {ID: degrees}). Nothing was "
                              "sent.", 400)
            self.not_busy()
            values, keys = {}, {}
            for key, deg in body["goals"].items():
                sid = V.servo_id(key, "ID")
                if sid in keys:  # '1' and '1.0': one servo, two goals
                    raise Refused("ID %d is given twice ('%s' and '%s'): give each servo "
                                  "one goal. Nothing was sent." % (sid, keys[sid], key), 400)
                keys[sid] = key
                values[sid] = self._goal(sid, deg, body["speed"])
            job = _group_job(self.st, values, how)
            clamps = await self.st.call(job, "IDs %s: move together (%s)" % (
                ", ".join(map(str, sorted(values))), "REG WRITE, broadcast ACTION"
                if how == "action" else "SYNC WRITE"), motion=True)
            from .moves import Moves
            said = {sid: Moves(self.st).clamped(sid, c) for sid, c in sorted(clamps.items())}
            extra = {"note": " ".join(n["note"] for n in said.values())} if said else {}
            return ok(ids=sorted(values),
                      clamped={sid: n["clamped"] for sid, n in said.items()}, **extra)
        return await self.handle(request, go)

    def _goal(self, sid, deg, speed):
        entry = self._entry(sid)
        variant = variant_by_model(entry["model"])
        if variant is None or not REGISTERS["acceleration"].applies_to(variant):
            raise Refused("ID %d is the %s: it runs in speed mode, so it has no goal to go "
                          "to. Nothing was sent." % (sid, entry["variant"]), 400)
        unit = self.st.resolutions.get(sid, 10) * 0.1
        top = variant.max_angle_ddeg / 10
        g = V.number(deg, "ID %d: goal" % sid, 0, top, "deg")
        s = V.number(speed, "speed", unit, 0x7FFF * unit, "deg/s")
        return {"goal_position": int(round(g / unit)),
                "moving_speed": max(1, int(round(s / unit)))}

    async def plan(self, request):
        """The planned reference of a trajectory from the servo's present position."""
        async def go(body):
            V.fields(body, ("points",), ("id",))
            sid = self.target(body)
            from .moves import Moves, angle_limits
            moves = Moves(self.st)
            points = moves._points(body["points"], sid)  # as the Motion panel's

            def job(bus):
                variant = bus.variant(sid)
                ramps = ("acceleration", "deceleration") if REGISTERS[
                    "acceleration"].applies_to(variant) else ("base_acceleration",
                                                              "base_deceleration")
                v = bus.read_many(sid, [variant.position_register.name, "angle_resolution",
                                        *ramps])
                return v, ramps, angle_limits(bus, sid)
            v, ramps, lim = await self.st.call(job)
            res = v["angle_resolution"] or 10
            start = v[[k for k in v if k in ("turned_angle", "present_position")][0]]
            # the servo clamps each point to its angle limits (src/traj.c): so does the plan
            held = [(min(max(a, lim[0]), lim[1]) if lim else a, sp) for a, sp in points]
            prof = planner.trajectory(start, held, res, v[ramps[0]], v[ramps[1]])
            deg = res * 0.1
            return ok(profile=[[t, round(p * deg, 2)] for t, p in prof],
                      duration=prof[-1][0], **moves.points_clamped(sid, points, lim))
        return await self.handle(request, go)

    async def config_save(self, request):
        async def go(body):
            V.fields(body, (), ("id",))
            sid = self.target(body)
            self.not_busy()
            return ok(config=await self.st.call(lambda bus: C.save(bus, sid)))
        return await self.handle(request, go)

    async def config_restore(self, request):
        async def go(body):
            V.fields(body, ("config",), ("id", "with_id", "with_baud", "confirm"))
            sid = self.target(body)
            flags = [V.flag(body.get(k, False), k) for k in ("with_id", "with_baud",
                                                              "confirm")]
            self.not_busy()
            changes, reasons, runs = await self.st.call(
                lambda bus: C.restore_plan(bus, sid, body["config"], flags[0], flags[1]))
            if "id" in changes:
                await self.st.call(lambda bus: bus.refuse_taken(changes["id"]))
            if reasons and not flags[2]:
                raise Refused("%s Confirm to restore it anyway. Nothing was written." %
                              sentence(reasons[0]), 409, confirm=sentence(reasons[0]))
            if changes:
                await self.st.call(self._restore_job(sid, changes),
                                   "ID %d: restore %d setting%s (%s)" % (
                                       sid, len(changes), "" if len(changes) == 1 else
                                       "s", ", ".join(changes)))
            if "id" in changes:  # the servo answers at its new ID: the studio follows it
                self.st.renumbered(sid, changes["id"])
                if self.st.selected == sid:
                    await self.st.call(self.st.select(changes["id"]))
                self.st.changed()
            self.st.table_due = 0.0
            return ok(changes=changes, writes=len(runs))
        return await self.handle(request, go)

    def _restore_job(self, sid, changes):
        st = self.st

        def job(bus):
            variant = bus.variant(sid)  # while it answers at this ID and baud
            C.restore(bus, sid, changes)
            if "angle_resolution" in changes:
                st.set_resolution(changes.get("id", sid), changes["angle_resolution"])
            if "baud_rate" in changes:  # written last (plan_write), at the new ID if any
                st.follow_baud(bus, changes.get("id", sid), changes["baud_rate"], variant)
        return job

    async def config_diff(self, request):
        async def go(body):
            V.fields(body, ("a", "b"))
            docs = []
            for side in ("a", "b"):
                given = body[side]
                if isinstance(given, dict):
                    C.check(given)
                    docs.append(given)
                else:
                    sid = V.servo_id(given, "ID")
                    docs.append(await self.st.call(lambda bus, s=sid: C.save(bus, s)))
            return ok(rows=C.diff(docs[0], docs[1]), a=docs[0], b=docs[1])
        return await self.handle(request, go)


def _tab(body):
    """The tab a plot or dashboard request is for (the page sends the name it gave its
    WebSocket; a script that sends none is one tab of its own)."""
    tab = body.get("tab", "")
    if not isinstance(tab, str) or len(tab) > 64:
        raise Refused("'tab' must be the page's tab name (text, at most 64 characters). "
                      "Nothing was sent.", 400)
    return tab


def _group_job(st, values, how):
    """The job of a group move; {ID: held_goal()} for the servos that clamped their
    goal to their angle limits. No goal is left held for a later ACTION: a REG WRITE of
    a move cut short (a servo that does not answer, a STOP) is replaced (Studio.unhold),
    and a broadcast ACTION is refused while a servo may hold one."""
    from .moves import held_goal

    def job(bus):
        if how == "sync":
            bus.sync_write("goal_position", values)
        else:
            left = st.unhold(bus, st.held - set(values)) if st.held - set(values) else []
            if left:
                raise Refused(
                    "ID %s may still hold the goal of a group move that was cut short (a "
                    "REG WRITE), and does not answer to have it replaced: this move's "
                    "broadcast ACTION would start it too. Make it answer again (or power "
                    "it off and on), or move with one SYNC WRITE. No goal was sent." %
                    ", ".join(map(str, left)), 409, sent=True)
            try:
                for sid, v in sorted(values.items()):
                    st.held.add(sid)  # held from now on, even if its answer is lost
                    bus.reg_write(sid, v)  # goal and speed (30-33), held until ACTION
            except ServoBusError as e:
                if not isinstance(e, Interrupted) and not is_link_error(e):
                    st.unhold(bus, set(values))  # STOP's job does it after a STOP
                raise
            bus.action(P.BROADCAST)  # every one of them starts at this packet
            st.held.clear()  # a broadcast ACTION empties every servo's buffer
        clamps = {}
        for sid, v in sorted(values.items()):
            c = held_goal(bus, sid, v["goal_position"])
            if c:
                clamps[sid] = c
        return clamps
    return job
