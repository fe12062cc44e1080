"""The studio's motion actions: STOP, move, speed mode, homing, trajectory. Each value
is checked by values.py before anything is queued; each motion job is marked as one,
so that a STOP cancels it while it waits in the queue."""

import asyncio

from .. import values as V
from ..registers import REGISTERS
from .api import Handler, ok
from .jobs import Refused

ACC_UNITS = "x10 deg/s^2"


def held_goal(bus, sid, goal):
    """After a goal was written (worker thread): None if the servo holds it, else (held,
    asked, CW limit, CCW limit) in position units — the servo clamps a goal to its angle
    limits (registers 6-9) and says nothing."""
    held = bus.read(sid, "goal_position")
    if held == goal:
        return None
    lim = bus.read_many(sid, ["cw_angle_limit", "ccw_angle_limit"])
    return held, goal, lim["cw_angle_limit"], lim["ccw_angle_limit"]


def angle_limits(bus, sid):
    """(CW, CCW) angle limits in position units that the servo clamps a goal or a
    trajectory point to, or None in speed mode (the base; both limits 0): src/regs.c
    regs_clamp_goal()."""
    variant = bus.variant(sid)
    if variant is not None and not REGISTERS["acceleration"].applies_to(variant):
        return None
    lim = bus.read_many(sid, ["cw_angle_limit", "ccw_angle_limit"])
    lo, hi = lim["cw_angle_limit"], lim["ccw_angle_limit"]
    return None if lo == 0 and hi == 0 else (lo, hi)


class Moves(Handler):
    """POST /api/stop, /api/move, /api/speed, /api/home, /api/traj."""

    def add_routes(self, app):
        for path, fn in (("stop", self.stop), ("move", self.move), ("speed", self.speed),
                         ("home", self.home), ("traj", self.traj)):
            app.router.add_post("/api/" + path, fn)

    def _top(self, factor, sid=None):
        """The largest position (or speed, factor 0x7FFF) in degrees at servo sid's
        resolution (default: the selected servo's)."""
        return factor * (self.st.resolution if sid is None else self.res(sid)) * 0.1

    async def stop(self, request):
        """STOP reads nothing of the request: it is never refused for its form. It is
        refused only when the bus is gone (then nothing can reach the servos)."""
        async def go(_):
            sent_at = await asyncio.wrap_future(self.st.request_stop())
            return ok(sent_at=round(sent_at - self.st.t0, 3))
        return await self.handle(request, go, read_body=False)

    async def move(self, request):
        async def go(body):
            V.fields(body, ("goal", "speed", "acc", "dec"), ("id",))
            sid = self.target(body)
            self.not_busy()
            goal = self.units(body["goal"], "goal", 0, self._top(0xFFFF, sid), sid=sid)
            speed = self.units(body["speed"], "speed", 0, self._top(0x7FFF, sid), "deg/s",
                               sid)
            if speed < 1:
                raise Refused("Speed %s deg/s is 0 position units/s: it would not move (0 "
                              "stops). Give at least %g deg/s. Nothing was sent." % (
                                  body["speed"], self._top(1, sid)), 400)
            acc = V.integer(body["acc"], "acceleration", 0, 255, ACC_UNITS)
            dec = V.integer(body["dec"], "deceleration", 0, 255, ACC_UNITS)

            def job(bus):
                if REGISTERS["acceleration"].applies_to(bus.variant(sid)):
                    # goal, speed, acceleration, deceleration (30-35) in one WRITE, so the
                    # goal register (and the plot) shows the target
                    bus.write(sid, {"goal_position": goal, "moving_speed": speed,
                                    "acceleration": acc, "deceleration": dec})
                    return held_goal(bus, sid, goal)
                # the base: ramps are EEPROM registers, CUSTOM MOVE carries them; its
                # goal is relative to where it is (no angle limits to clamp to)
                bus.move_absolute(sid, goal, speed, acc, dec)
                return None
            clamp = await self.st.call(job, "ID %d: move to %s deg at %s deg/s (acc %d, "
                                       "dec %d)" % (sid, body["goal"], body["speed"], acc,
                                                    dec), motion=True)
            return ok(**self.clamped(sid, clamp))
        return await self.handle(request, go)

    def clamped(self, sid, clamp):
        """The answer's fields for a goal the servo clamped (clamp: held_goal()'s), with
        the sentence the page shows."""
        if not clamp:
            return {}
        held, asked, lo, hi = (round(v * self.st.resolutions.get(sid, 10) * 0.1, 2)
                               for v in clamp)
        if lo <= asked <= hi:  # not a clamp: the servo did not take the move at all
            note = ("ID %d did not take the goal of %g deg (its goal is %g deg): an arm, "
                    "wrist or finger refuses motion until it is homed, and an unload "
                    "refuses it too (Safety)." % (sid, asked, held))
        else:
            note = ("ID %d: %g deg is outside its angle limits (%g..%g deg): it goes to "
                    "%g deg instead (the servo clamps the goal)." % (sid, asked, lo, hi,
                                                                      held))
        return {"clamped": {"asked": asked, "held": held, "limits": [lo, hi]},
                "note": note}

    async def speed(self, request):
        async def go(body):
            V.fields(body, ("speed",), ("id",))
            sid = self.target(body)
            self.not_busy()
            top = self._top(0x7FFF, sid)
            v = self.units(body["speed"], "speed", -top, top, "deg/s", sid)
            if v:
                await self.st.call(lambda bus: self._speed_mode(bus, sid))
            await self.st.call(lambda bus: bus.set_speed(sid, v), "ID %d: speed mode at %s "
                               "deg/s" % (sid, body["speed"]), motion=True)
            return ok()
        return await self.handle(request, go)

    @staticmethod
    def _speed_mode(bus, sid):
        """Refused (409) if sid is in position mode, where a speed only sets the cruise
        speed of the next move (the base is always in speed mode)."""
        if not REGISTERS["acceleration"].applies_to(bus.variant(sid)):
            return
        lim = bus.read_many(sid, ["cw_angle_limit", "ccw_angle_limit"])
        if lim["cw_angle_limit"] or lim["ccw_angle_limit"]:
            raise Refused(
                "ID %d is in position mode (angle limits %d and %d): a speed there is only "
                "the cruise speed of the next move. For speed mode set cw_angle_limit and "
                "ccw_angle_limit to 0 in the control table. Nothing was written." % (
                    sid, lim["cw_angle_limit"], lim["ccw_angle_limit"]), 409)

    async def home(self, request):
        async def go(body):
            V.fields(body, ("start",), ("id",))
            start = V.flag(body["start"], "start")  # "no" is not false: refused
            sid = self.target(body)
            self.not_busy()
            await self.st.call(lambda bus: bus.home(sid) if start else bus.stop_homing(sid),
                               "ID %d: %s homing" % (sid, "start" if start else "stop"),
                               motion=start)
            return ok()
        return await self.handle(request, go)

    async def traj(self, request):
        async def go(body):
            V.fields(body, ("points",), ("id",))
            sid = self.target(body)
            self.not_busy()
            points = self._points(body["points"], sid)

            def job(bus):
                lim = angle_limits(bus, sid)
                bus.trajectory_write(sid, points)
                bus.trajectory_action(sid)
                return lim
            lim = await self.st.call(job, "ID %d: trajectory of %d points, run" % (
                sid, len(points)), motion=True)
            return ok(**self.points_clamped(sid, points, lim))
        return await self.handle(request, go)

    def points_clamped(self, sid, points, lim):
        """The answer's note for trajectory points outside the angle limits lim (the
        servo clamps each: src/traj.c), or nothing."""
        outside = [n for n, (a, _) in enumerate(points, 1) if lim and not
                   lim[0] <= a <= lim[1]]
        if not outside:
            return {}
        deg = self.st.resolutions.get(sid, 10) * 0.1
        return {"outside": outside, "note": "ID %d: point%s %s (%s deg) %s outside its angle "
                "limits (%g..%g deg): the servo goes to the nearest limit instead." % (
                    sid, "s" if len(outside) > 1 else "", ", ".join(map(str, outside)),
                    ", ".join("%g" % round(points[n - 1][0] * deg, 2) for n in outside),
                    "are" if len(outside) > 1 else "is", round(lim[0] * deg, 2),
                    round(lim[1] * deg, 2))}

    def _points(self, given, sid=None):
        """[(angle, speed)] in position units from [[deg, deg/s], ...] (1 to 63)."""
        if not isinstance(given, list) or not given:
            raise Refused("The trajectory has no points: give [[angle, speed], ...]. "
                          "Nothing was sent.", 400)
        if len(given) > 63:
            raise Refused("%d points do not fit in one TRAJECTORY WRITE (63 at most). "
                          "Nothing was sent." % len(given), 400)
        points = []
        for n, p in enumerate(given, 1):
            if not isinstance(p, list) or len(p) != 2:
                raise Refused("Point %d is not [angle, speed]. Nothing was sent." % n, 400)
            angle = self.units(p[0], "point %d: angle" % n, 0, self._top(0xFFFF, sid),
                               sid=sid)
            speed = self.units(p[1], "point %d: speed" % n, 0, self._top(0xFFFF, sid),
                               "deg/s", sid)
            if speed < 1:
                raise Refused("Point %d: speed %s deg/s is 0 position units/s (a point "
                              "needs a speed). Nothing was sent." % (n, p[1]), 400)
            points.append((angle, speed))
        return points
