"""The control table over the bus: READ, WRITE, REG WRITE/ACTION, SYNC WRITE, the whole
table, the ID and a factory reset."""

import time

from . import protocol as P
from .errors import (BusTimeout, DuplicateId, IdTaken, NotApplied, ProtocolError,
                     RangeError, ServoBusError, ServoFault)
from .link import _MOTION_HINT, SESSION_HINT, check_id
from .registers import REGISTERS, TABLE_SIZE, VARIANTS, register, variant_by_model

_WRITE_HINT = ("a value out of range, a read-only, reserved or not-applicable register, "
               "a CW limit above the CCW limit, a motion command the servo refuses now, "
               "or " + SESSION_HINT)
# Registers whose read-back differs from what was written by design: the goal is clamped
# to the limits, clear_unload reads 0, homing reports its state in the high nibble.
_NO_READBACK = ("goal_position", "clear_unload", "homing")
# Seconds a RESET that was not answered is given to show up at ID 1.
RESET_SETTLE_S = 1.0


def _all_variants(r):
    return set(r.variants) == set(VARIANTS)


class Control:
    """Register access (a mixin of Bus: it uses Link's transactions)."""

    _unchanged = False  # write_many() found the WRITE's EEPROM values already there

    def read_raw(self, servo_id, address, count):
        """READ count bytes from address; returns bytes."""
        if not (0 <= address < TABLE_SIZE and 1 <= count <= TABLE_SIZE - address):
            raise RangeError("READ %d bytes from %d is outside the table (addresses 0-%d)"
                             % (count, address, TABLE_SIZE - 1))
        pkt = self.transact(servo_id, P.READ, bytes([address, count]),
                            "READ %d bytes from %d" % (count, address), nbytes=6 + count)
        if len(pkt.params) != count:
            raise ProtocolError("ID %d answered READ of %d bytes with %d" % (
                servo_id, count, len(pkt.params)))
        return pkt.params

    def read(self, servo_id, reg):
        """Value of one register (name or address), decoded (signed where it is)."""
        r = register(reg)
        data = self.read_raw(servo_id, r.address, r.size)
        return r.decode(int.from_bytes(data, "little"))

    def read_many(self, servo_id, regs):
        """Several registers in one READ (from the lowest to the highest): a dict."""
        rs = [register(x) for x in regs]
        lo = min(r.address for r in rs)
        hi = max(r.address + r.size for r in rs)
        data = self.read_raw(servo_id, lo, hi - lo)
        return {r.name: r.decode(int.from_bytes(data[r.address - lo:r.address - lo + r.size],
                                                "little")) for r in rs}

    def variant(self, servo_id):
        """The servo's variant (from its model number; cached per ID), or None. A live
        fault bit in the answer (a latched unload) does not stop it being read."""
        if servo_id not in self._variants:
            try:
                model = self.read(servo_id, "model_number")
            except ServoFault as e:
                if len(e.params) != 2:
                    raise
                model = int.from_bytes(e.params, "little")
            self._variants[servo_id] = variant_by_model(model)
        return self._variants[servo_id]

    def resolution(self, servo_id):
        return self.read(servo_id, "angle_resolution")

    def encode(self, regs_values, variant=None):
        """(address, bytes) of one WRITE of {register: value} (contiguous registers),
        range-checked against the table; RangeError before anything is sent."""
        items = sorted(((register(k), v) for k, v in dict(regs_values).items()),
                       key=lambda rv: rv[0].address)
        if not items:
            raise RangeError("nothing to write")
        data = b""
        address = items[0][0].address
        for r, value in items:
            if r.address != address + len(data):
                raise RangeError("registers %s are not contiguous: one WRITE covers one run "
                                 "of registers without gaps" % ", ".join(x.name for x, _ in items))
            if not r.writable:
                raise RangeError("%s (register %d) is read-only" % (r.name, r.address))
            if not r.applies_to(variant):
                raise RangeError("%s (register %d) does not exist on the %s (it is for %s)" %
                                 (r.name, r.address, variant.name, ", ".join(r.variants)))
            data += r.encode(value).to_bytes(r.size, "little")
        return address, data

    def write(self, servo_id, reg, value=None, check_variant=True):
        """WRITE one register (name or address) or, with a dict, several contiguous ones
        in one packet. Values are in the register's unit (signed for speeds)."""
        regs_values = reg if isinstance(reg, dict) else {reg: value}
        check_id(servo_id, broadcast=True)
        variant = None
        if check_variant and servo_id != P.BROADCAST and \
                not all(_all_variants(register(k)) for k in regs_values):
            variant = self.variant(servo_id)
        address, data = self.encode(regs_values, variant)
        named = {register(k).name: v for k, v in regs_values.items()}
        names = ", ".join("%s=%s" % kv for kv in named.items())
        motion = any(n in ("goal_position", "moving_speed", "homing") for n in named)
        self.commit_wait = None
        pkt = self.transact(servo_id, P.WRITE, bytes([address]) + data, "WRITE " + names,
                            hint=_MOTION_HINT if motion else _WRITE_HINT, motion=motion)
        if servo_id == P.BROADCAST:
            return
        if any(register(n).area == "EEPROM" for n in named) and not self._unchanged:
            self.commit_wait = self.commit_budget.commit(self.budget_key(servo_id))
        if pkt is None:
            self._verify_silent(servo_id, named, "WRITE " + names)
        elif "status_return_level" in named:
            self._note_level(servo_id, named["status_return_level"])
        if "id" in named and named["id"] != servo_id:
            self._variants.pop(servo_id, None)
            self.commit_budget.moved(self.budget_key(servo_id), self.budget_key(named["id"]))
            level = self._levels.pop(servo_id, None)
            if level is not None:
                self._levels[named["id"]] = level

    def _note_level(self, servo_id, level):
        if level < 2:
            self._levels[servo_id] = level
        else:
            self._levels.pop(servo_id, None)

    def _verify_silent(self, servo_id, named, what):
        """A WRITE the servo did not answer (status return level 0 or 1): check what can
        be checked. A new ID: PING it there. Register 16 set to 1 or 2: READ it back. At
        level 1: READ the other registers back. At level 0 nothing else can be checked
        (self.confirmed stays False)."""
        level = self._levels.get(servo_id, 0)
        at = named.get("id", servo_id)
        if "id" in named and not self.present(at, timeout=self.full_answer_time()):
            raise NotApplied("ID %d did not move to ID %d: nothing answers PING there (it "
                             "does not answer writes at status return level %d, so it "
                             "cannot say why)" % (servo_id, at, level))
        if "status_return_level" in named:
            level = named["status_return_level"]
            if level == 0:
                self._levels[at] = 0
                self.confirmed = "id" in named
                return
            self._levels[at] = level  # a READ is answered again from now on
        if level == 0:
            self.confirmed = "id" in named
            return
        check = {n: v for n, v in named.items() if n not in _NO_READBACK and n != "id"}
        if not check:
            self.confirmed = "id" in named
            return
        try:
            got = self.read_many(at, list(check))
        except BusTimeout:
            raise NotApplied("ID %d did not take %s: it still does not answer READ" % (
                at, what)) from None
        wrong = {n: got[n] for n, v in check.items() if got[n] != v}
        if wrong:
            raise NotApplied("ID %d did not take %s: it reads %s (it answers only READ "
                             "and PING at status return level %d, so it cannot say why)" %
                             (at, what, ", ".join("%s=%s" % kv for kv in wrong.items()),
                              level))
        self._note_level(at, named.get("status_return_level", level))
        self.confirmed = True

    def plan_write(self, servo_id, regs_values):
        """Check a set of {register: value} against everything known before sending any
        of it: each value's range, that the register is writable and exists on the
        servo's variant, and CW limit <= CCW limit with the values being written (the
        other limit read from the servo if only one is written). Returns the WRITEs to
        send: [(address, {register name: value})], one per contiguous run of registers
        (a single WRITE when they are contiguous; the run with a new ID or baud last).
        RangeError, nothing sent."""
        named = {}
        for k, v in dict(regs_values).items():
            r = register(k)
            if r.name in named:
                raise RangeError("%s is given twice" % r.name)
            named[r.name] = v
        if not named:
            raise RangeError("nothing to write")
        variant = None
        if not all(_all_variants(register(n)) for n in named):
            variant = self.variant(servo_id)
        for n, v in named.items():
            self.encode({n: v}, variant)
        if "cw_angle_limit" in named or "ccw_angle_limit" in named:
            limits = dict(named)
            missing = [n for n in ("cw_angle_limit", "ccw_angle_limit") if n not in named]
            if missing:
                limits.update(self.read_many(servo_id, missing))
            if limits["cw_angle_limit"] > limits["ccw_angle_limit"]:
                raise RangeError(
                    "cw_angle_limit %d would be above ccw_angle_limit %d (%s): the CW limit "
                    "is the lower one; write both, the lower as cw_angle_limit" % (
                        limits["cw_angle_limit"], limits["ccw_angle_limit"],
                        "both given" if not missing else "%s read from ID %d" % (
                            missing[0], servo_id)))
        runs = []
        for n in sorted(named, key=lambda x: register(x).address):
            r = register(n)
            if runs and runs[-1][2] == r.address:
                runs[-1][1][n] = named[n]
                runs[-1][2] = r.address + r.size
            else:
                runs.append([r.address, {n: named[n]}, r.address + r.size])
        # The run that moves the servo (a new ID or baud) goes last: the others still
        # reach it where it is.
        runs.sort(key=lambda run: "id" in run[1] or "baud_rate" in run[1])
        return [(a, rv) for a, rv, _ in runs]

    def write_many(self, servo_id, regs_values):
        """All or nothing: plan_write() checks every value first, then one WRITE per
        contiguous run (one WRITE when the registers are contiguous, which the servo
        applies whole or not at all). If a later WRITE is refused, the earlier ones are
        written back to the values read before (best effort) and the refusal raised.
        Returns the runs written."""
        runs = self.plan_write(servo_id, regs_values)
        waits, confirmed = [], True
        before = []
        if len(runs) > 1:
            for _, rv in runs:
                readable = [n for n in rv if register(n).readable and n not in _NO_READBACK]
                before.append(self.read_many(servo_id, readable) if readable else {})
        for i, (_, rv) in enumerate(runs):
            try:
                self._unchanged = self._same_eeprom(servo_id, rv)
                self.write(servo_id, rv, check_variant=False)
                waits.append(self.commit_wait)
                confirmed = confirmed and self.confirmed
            except ServoBusError:
                for j in range(i):
                    if before[j]:
                        try:
                            self.write(servo_id, before[j], check_variant=False)
                        except ServoBusError:
                            pass
                raise
            finally:
                self._unchanged = False
        known = [w for w in waits if w is not None]
        self.commit_wait = max(known) if known else None  # the longest of the WRITEs
        self.confirmed = confirmed
        return runs

    def _same_eeprom(self, servo_id, rv):
        """True if every register of rv is EEPROM and already holds its value: the WRITE
        costs no flash commit (docs/persistence.md). False when unsure."""
        if not all(register(n).area == "EEPROM" and register(n).readable for n in rv):
            return False
        try:
            return self.read_many(servo_id, list(rv)) == dict(rv)
        except ServoBusError:
            return False

    def write_raw(self, servo_id, address, data):
        """WRITE raw bytes at address (no checks in the SDK; the servo validates)."""
        self.transact(servo_id, P.WRITE, bytes([address]) + bytes(data),
                      "WRITE %d bytes at %d" % (len(data), address), hint=_WRITE_HINT)

    def reg_write(self, servo_id, reg, value=None):
        """REG WRITE: validated and held until ACTION (register 44 reads 1 meanwhile)."""
        regs_values = reg if isinstance(reg, dict) else {reg: value}
        variant = self.variant(servo_id) if servo_id != P.BROADCAST else None
        address, data = self.encode(regs_values, variant)
        self.transact(servo_id, P.REG_WRITE, bytes([address]) + data, "REG WRITE",
                      hint=_WRITE_HINT)

    def action(self, servo_id=P.BROADCAST):
        """ACTION: apply the held REG WRITE (broadcast by default: all at once)."""
        self.transact(servo_id, P.ACTION, what="ACTION",
                      hint="nothing was held by a REG WRITE, or the held write is refused now")

    def sync_write(self, reg, values):
        """SYNC WRITE (broadcast, no answers): values maps ID -> value, or ID -> dict of
        contiguous registers. Every value is range-checked before anything is sent."""
        slices = []
        address = length = None
        for servo_id, v in sorted(values.items()):
            if not 0 <= servo_id <= P.ID_MAX:
                raise RangeError("SYNC WRITE: ID %r is not 0-253" % (servo_id,))
            a, data = self.encode(v if isinstance(v, dict) else {reg: v})
            if address is None:
                address, length = a, len(data)
            elif (a, len(data)) != (address, length):
                raise RangeError("SYNC WRITE: every servo's slice must cover the same registers")
            slices.append(bytes([servo_id]) + data)
        if not slices:
            raise RangeError("SYNC WRITE: no servo given")
        params = bytes([address, length]) + b"".join(slices)
        if len(params) > 253:
            raise RangeError("SYNC WRITE: %d servos x %d bytes do not fit in one packet" %
                             (len(slices), length))
        self.send(P.BROADCAST, P.SYNC_WRITE, params)

    def dump(self, servo_id):
        """The whole table in one READ: a list of (Register, value or None where the
        register is not applicable/readable on this variant)."""
        variant = self.variant(servo_id)
        data = self.read_raw(servo_id, 0, TABLE_SIZE)
        out = []
        for r in REGISTERS.values():
            if not r.applies_to(variant) or not r.readable:
                out.append((r, None))
                continue
            raw = int.from_bytes(data[r.address:r.address + r.size], "little")
            out.append((r, r.decode(raw)))
        return out

    # ---- configuration --------------------------------------------------------------

    def set_id(self, servo_id, new_id, check_free=True, check_duplicate=True):
        """Give servo_id the ID new_id. Refuses (IdTaken) if a servo answers at new_id,
        and (DuplicateId) if two servos answer at servo_id: both would move. The answer
        comes from the old ID; afterwards the servo answers at the new."""
        check_id(servo_id)
        if isinstance(new_id, bool) or not isinstance(new_id, int) or \
                not 0 <= new_id <= P.ID_MAX:
            raise RangeError("ID %r is out of range 0..253" % (new_id,))
        if new_id == servo_id:
            return
        if check_duplicate and self.duplicate(servo_id):
            raise DuplicateId(
                "two servos answer at ID %d: a new ID would go to both (see \"Two servos "
                "on one ID\" in tools/python/README.md)" % servo_id)
        self.ping(servo_id)  # the servo to change must be there
        if check_free:
            self.refuse_taken(new_id)
        self.write(servo_id, "id", new_id, check_variant=False)
        self._variants.pop(servo_id, None)

    def refuse_taken(self, new_id):
        """IdTaken if a servo answers a PING at new_id: two PINGs with the full time-out,
        so that one lost or late answer does not make a taken ID look free."""
        if any(self.present(new_id, timeout=self.full_answer_time()) for _ in range(2)):
            raise IdTaken("ID %d is already taken on the bus (a servo answered a PING "
                          "there); choose another ID or move that servo first" % new_id)

    def reset(self, servo_id, check_free=True):
        """RESET to factory values (ID 1, default baud...); answered with the old ID.
        Refuses (IdTaken) if another servo answers at ID 1, where this one would land.
        A servo that does not answer it (status return level 0 or 1) is looked for at
        ID 1 afterwards."""
        check_id(servo_id)
        if check_free and servo_id != 1:
            self.refuse_taken(1)
        try:
            pkt = self.transact(servo_id, P.RESET, what="RESET")
        except BusTimeout:
            if not self._reset_took(servo_id):
                raise
            pkt = None
        if pkt is None and self._reset_took(servo_id):
            self.confirmed = True
        self.commit_wait = self.commit_budget.commit(self.budget_key(servo_id))
        if servo_id != 1:
            self.commit_budget.moved(self.budget_key(servo_id), self.budget_key(1))
        self._variants.clear()
        self._levels.pop(servo_id, None)
        self._levels.pop(1, None)

    def _reset_took(self, servo_id):
        """After a RESET that was not answered: does a servo at factory settings answer
        at ID 1 (level 2 again: it answers READ)?"""
        deadline = time.monotonic() + RESET_SETTLE_S
        while True:
            saved, self.timeout = self.timeout, None
            try:
                if self.read_raw(1, 16, 1)[0] == 2:
                    return True
            except ProtocolError:  # garbled at ID 1: it landed on another servo there
                if servo_id != 1 and not self.present(servo_id):
                    return True
            except ServoBusError:
                pass
            finally:
                self.timeout = saved
            if time.monotonic() > deadline:
                return False
            time.sleep(0.05)
