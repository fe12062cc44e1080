"""Motion over the bus: position and speed mode, trajectories, CUSTOM MOVE, homing."""

import time
from collections import namedtuple

from . import protocol as P
from . import values as V
from .errors import RangeError, ServoBusError
from .link import _MOTION_HINT
from .registers import REGISTERS

HomingStatus = namedtuple("HomingStatus", "requested state text")

HOMING_STATES = {0: "never run", 1: "running", 2: "done", 3: "failed or aborted"}


class Motion:
    """Motion commands (a mixin of Bus: it uses Link's transactions and Control's writes)."""

    def position_register(self, servo_id):
        """The register that holds servo_id's present position (§8)."""
        v = self.variant(servo_id)
        return v.position_register if v else REGISTERS["turned_angle"]

    def position(self, servo_id):
        return self.read(servo_id, self.position_register(servo_id))

    def move(self, servo_id, position, speed=None):
        """Position mode: write the goal (and the moving speed) in one WRITE."""
        if speed is None:
            self.write(servo_id, "goal_position", position)
        else:
            self.write(servo_id, {"goal_position": position, "moving_speed": speed})

    def set_speed(self, servo_id, speed):
        """Moving speed in position units/s, negative for the negative direction; in
        speed mode this turns the motor; 0 stops (rule 3)."""
        self.write(servo_id, "moving_speed", speed)

    def stop(self, servo_id):
        """Speed 0: stops whatever the motor is doing (PROTOCOL.md rule 3)."""
        self.write(servo_id, "moving_speed", 0)

    def stop_all_now(self):
        """Moving speed 0 to every servo (broadcast) at once: what a STOP button sends.
        It does not wait for a late answer to an earlier request to pass, nor look at
        stop_event: a STOP is never late. It does not go into an answer either: an
        interrupted wait returns at a packet boundary (Link._read), and a servo that
        has yet to answer holds its answer while a packet arrives (PROTOCOL.md §1;
        src/link.c: never talk over a frame that is still arriving)."""
        address, data = self.encode({"moving_speed": 0})
        pkt = P.instruction(P.BROADCAST, P.WRITE, bytes([address]) + data)
        self._t.flush_input()
        self._put(pkt)
        return pkt

    def brake(self, servo_id, on=True):
        self.write(servo_id, "brake", 1 if on else 0)

    def start_end(self, servo_id, what):
        """START/END: 'start' makes the present position 0 and the CW limit; 'end' makes
        it the CCW limit."""
        codes = {"start": 1, "end": 2, 1: 1, 2: 2}
        if isinstance(what, bool) or not isinstance(what, (str, int)) or what not in codes:
            raise RangeError("START/END: %r is not 'start' or 'end'" % (what,))
        code = codes[what]
        before = self._limits_for_budget(servo_id)
        self.transact(servo_id, P.START_END, bytes([code]), "START/END %s" % what,
                      motion=True)
        self._limits_committed(servo_id, before)

    # ---- the commit budget of what the servo sets itself (budget.py) ----------------

    def _limits_for_budget(self, servo_id):
        """The angle limits (registers 6-9) before a command that sets them itself, or
        None (broadcast, or not readable: the estimate then counts a commit)."""
        if servo_id == P.BROADCAST:
            return None
        try:
            return self.read_raw(servo_id, REGISTERS["cw_angle_limit"].address, 4)
        except ServoBusError:
            return None

    def _limits_committed(self, servo_id, before):
        """The servo commits its limits when they changed (START/END, homing done)."""
        if servo_id == P.BROADCAST:
            return
        if before is not None and self._limits_for_budget(servo_id) == before:
            return
        self.commit_wait = self.commit_budget.commit(self.budget_key(servo_id))

    def trajectory_write(self, servo_id, points, point_size=None):
        """TRAJECTORY WRITE of [(angle, speed), ...] (position units, units/s; speed > 0).
        The 4-byte point form is used when it fits (63 points), else the 3-byte form
        (speeds up to 255, 84 points). An empty list clears the stored trajectory."""
        if not isinstance(points, (list, tuple)) or not all(
                isinstance(p, (list, tuple)) and len(p) == 2 for p in points):
            raise RangeError("trajectory points: give a list of (angle, speed) pairs")
        points = [(V.strict_integer(a, "trajectory angle"),
                   V.strict_integer(s, "trajectory speed")) for a, s in points]
        if point_size not in (None, 3, 4) or isinstance(point_size, bool):
            raise RangeError("point size %r: give 3, 4 or None" % (point_size,))
        for a, s in points:
            if not 0 <= a <= 0xFFFF:
                raise RangeError("trajectory angle %d is out of range 0..65535" % a)
            if not 1 <= s <= 0xFFFF:
                raise RangeError("trajectory speed %d is out of range 1..65535 (0 is not "
                                 "allowed in a point)" % s)
        if point_size is None:
            point_size = 4 if len(points) <= 63 else 3
        if point_size == 3 and any(s > 255 for _, s in points):
            raise RangeError("the 3-byte point form carries speeds up to 255")
        if len(points) > (84 if point_size == 3 else 63):
            raise RangeError("%d points do not fit in one packet (%d at most in the %d-byte "
                             "form)" % (len(points), 84 if point_size == 3 else 63, point_size))
        params = bytes([len(points)])
        for a, s in points:
            params += P.u16(a) + (P.u16(s) if point_size == 4 else bytes([s]))
        self.transact(servo_id, P.TRAJ_WRITE, params,
                      "TRAJECTORY WRITE of %d points" % len(points))

    def trajectory_action(self, servo_id):
        """Run the stored trajectory."""
        self.transact(servo_id, P.TRAJ_ACTION, what="TRAJECTORY ACTION", motion=True,
                      hint="no trajectory stored, or " + _MOTION_HINT)

    def move_relative(self, servo_id, delta, speed, acc=None, dec=None):
        """CUSTOM MOVE sub 1: move by delta position units (sign = direction) at speed
        (units/s), with acceleration/deceleration (registers 34/35 units) if given."""
        V.strict_integer(delta, "CUSTOM MOVE distance", -0xFFFF, 0xFFFF)
        V.strict_integer(speed, "CUSTOM MOVE speed", -0x7FFF, 0x7FFF)
        return self._custom(servo_id, 0x01, abs(delta), (0x8000 if delta < 0 else 0) |
                            abs(speed), acc, dec, "CUSTOM MOVE relative %+d" % delta)

    def move_absolute(self, servo_id, position, speed, acc=36, dec=36):
        """CUSTOM MOVE sub 2: absolute move to position at speed with ramps."""
        V.strict_integer(position, "CUSTOM MOVE position")
        V.strict_integer(speed, "CUSTOM MOVE speed", -0x7FFF, 0x7FFF)
        return self._custom(servo_id, 0x02, position, abs(speed), acc, dec,
                            "CUSTOM MOVE to %d" % position)

    def _custom(self, servo_id, sub, target, speed, acc, dec, what):
        if not 0 <= target <= 0xFFFF:
            raise RangeError("%s: %d is out of range 0..65535" % (what, target))
        if not 0 <= (speed & 0x7FFF) <= 0x7FFF or speed > 0xFFFF:
            raise RangeError("%s: speed out of range (magnitude 0..32767)" % what)
        params = bytes([sub]) + P.u16(target) + P.u16(speed)
        if (acc is None) != (dec is None):
            raise RangeError("%s: give both acceleration and deceleration, or neither" % what)
        if acc is not None:
            for name, v in (("acceleration", acc), ("deceleration", dec)):
                V.strict_integer(v, "%s: %s" % (what, name))
                if not 0 <= v <= 255:
                    raise RangeError("%s: %s %d is out of range 0..255" % (what, name, v))
            params += bytes([acc, dec])
        self.transact(servo_id, P.CUSTOM, params, what, motion=True)

    # ---- homing ---------------------------------------------------------------------

    def home(self, servo_id):
        """Start homing (register 24 = 1); see homing_status()/wait_homed()."""
        before = self._limits_for_budget(servo_id)
        self.write(servo_id, "homing", 1)
        self.__dict__.setdefault("_homing_limits", {})[servo_id] = before

    def stop_homing(self, servo_id):
        self.write(servo_id, "homing", 0)

    def homing_status(self, servo_id):
        """HomingStatus(requested, state, text) from register 24 (low nibble as written,
        high nibble 0 never, 1 running, 2 done, 3 failed)."""
        raw = self.read(servo_id, "homing")
        state = raw >> 4
        homing = self.__dict__.get("_homing_limits", {})
        if state != 1 and servo_id in homing:  # over: done commits the limits it measured
            before = homing.pop(servo_id)
            if state == 2:
                self._limits_committed(servo_id, before)
        return HomingStatus(raw & 0x0F, state, HOMING_STATES.get(state, "state %d" % state))

    def wait_homed(self, servo_id, timeout=30.0, poll=0.1):
        """Wait until homing is done; raise ServoBusError if it failed or timed out."""
        V.seconds(timeout, "homing time-out", 0.0, 86400.0)
        V.seconds(poll, "poll interval", 0.0, 60.0)
        deadline = time.monotonic() + timeout
        while True:
            st = self.homing_status(servo_id)
            if st.state == 2:
                return st
            if st.state == 3:
                raise ServoBusError("ID %d: homing failed or was aborted (a switch not found "
                                    "within the maximum travel, both switches high, a stall, "
                                    "or a stop)" % servo_id)
            if time.monotonic() > deadline:
                raise ServoBusError(
                    "ID %d: homing not done after %.0f s (status: %s)%s" % (
                        servo_id, timeout, st.text,
                        " — it never started (no photo switches on a foot or base)"
                        if st.state == 0 else ""))
            self.pause(poll)

