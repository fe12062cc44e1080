"""The control table over the bus: READ, WRITE, all-or-nothing sets, REG WRITE/ACTION,
SYNC WRITE and the whole table (IDs and factory reset: identity.py)."""

from . import protocol as P
from . import values as V
from .errors import (BusTimeout, DuplicateId, InstructionError, Interrupted, NotApplied,
                     ProtocolError, RangeError, ServoBusError, ServoFault)
from .link import _MOTION_HINT, SESSION_HINT, check_id
from .registers import (REGISTERS, TABLE_SIZE, VARIANTS, Variant, register,
                        variant_by_model)

_WRITE_HINT = ("a value out of range, a read-only, reserved or not-applicable register, "
               "a CW limit above the CCW limit, a motion command the servo refuses now, "
               "or " + SESSION_HINT)
# Registers whose read-back differs from what was written by design: the goal is clamped
# to the limits, clear_unload reads 0, homing reports its state in the high nibble.
_NO_READBACK = ("goal_position", "clear_unload", "homing")


def _all_variants(r):
    return set(r.variants) == set(VARIANTS)


def _touches_eeprom(regs_values):
    """Does a write of these registers (names or addresses) reach the flash store?"""
    return any(register(k).area == "EEPROM" for k in regs_values)


class Control:
    """Register access (a mixin of Bus: it uses Link's transactions)."""

    _unchanged = False  # write_many() found the WRITE's EEPROM values already there

    @property
    def _held_eeprom(self):
        """Per ID: does the write a REG WRITE holds there touch EEPROM (its ACTION then
        spends a commit)? Broadcast REG WRITEs are held under the broadcast ID."""
        held = self.__dict__.get("_held")
        if held is None:
            held = self.__dict__["_held"] = {}
        return held

    def read_raw(self, servo_id, address, count):
        """READ count bytes from address; returns bytes."""
        _check_span(address, count)
        pkt = self.transact(servo_id, P.READ, bytes([address, count]),
                            "READ %d bytes from %d" % (count, address), nbytes=6 + count)
        if len(pkt.params) != count:
            raise ProtocolError("ID %d answered READ of %d bytes with %d" % (
                servo_id, count, len(pkt.params)))
        return pkt.params

    def read_alone(self, servo_id, address, count):
        """READ count bytes from address, listening for the whole answer window: the
        bytes, when one servo answers. Two servos at the ID (two answers, or answers
        that garble each other, confirmed by duplicate()) raise DuplicateId, so that
        values of two servos are never mixed. No answer, or an error answer: read_raw()
        once more, whose errors say why (level 0, absent, update mode)."""
        check_id(servo_id)
        _check_span(address, count)
        frame = P.instruction(servo_id, P.READ, bytes([address, count]))
        answers, garbled = self.listen(servo_id, frame,
                                       lambda pkt: len(pkt.params) == count, 6 + count)
        if len(answers) > 1 or (garbled and self.duplicate(servo_id)):
            raise DuplicateId(
                "two servos answer at ID %d (%s): their values would be mixed; see \"Two "
                "servos on one ID\" in tools/python/README.md" % (
                    servo_id, "two answers to one READ" if len(answers) > 1 else
                    "their answers garble each other"))
        if not answers:
            return self.read_raw(servo_id, address, count)
        self.last_err = answers[0].err
        self._check(servo_id, answers[0].err, "READ %d bytes from %d" % (count, address),
                    "", answers[0].params, False)
        return answers[0].params

    def read(self, servo_id, reg):
        """Value of one register (name or address), decoded (signed where it is)."""
        r = register(reg)
        data = self.read_raw(servo_id, r.address, r.size)
        return r.decode(int.from_bytes(data, "little"))

    def read_many(self, servo_id, regs):
        """Several registers in one READ (from the lowest to the highest): a dict."""
        rs = [register(x) for x in V.names(regs, "registers")]
        lo = min(r.address for r in rs)
        hi = max(r.address + r.size for r in rs)
        data = self.read_raw(servo_id, lo, hi - lo)
        return {r.name: r.decode(int.from_bytes(data[r.address - lo:r.address - lo + r.size],
                                                "little")) for r in rs}

    def variant(self, servo_id):
        """The servo's variant (from its model number; cached per ID), or None. A live
        fault bit in the answer (a latched unload) does not stop it being read."""
        check_id(servo_id)
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
        if variant is not None and not isinstance(variant, Variant):
            raise RangeError("variant %r: give a servobus.registers.Variant or None" %
                             (variant,))
        items = sorted(((register(k), v) for k, v in
                        V.mapping(regs_values, "registers").items()),
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
        regs_values = reg if isinstance(reg, dict) else {register(reg).name: value}
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
        check_id(servo_id)
        for k, v in V.mapping(regs_values, "registers").items():
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
        """All or nothing for settings: plan_write() checks every value first, then one
        WRITE per contiguous run (one WRITE when the registers are contiguous, which the
        servo applies whole or not at all). If a later WRITE is refused, the earlier
        ones are written back to the values read before (best effort) and the refusal
        raised. clear_unload (register 25) is an action, not a setting: it is sent after
        the settings (before a new ID or baud), alone, by clear_unload(), which tries it
        again while the servo still sees the cause; nothing else is sent again, and a
        clear refused for good leaves the settings written (they are what removes the
        cause) and raises. Returns the runs written."""
        named = {}
        for k, v in V.mapping(regs_values, "registers").items():
            if register(k).name in named:
                raise RangeError("%s is given twice" % register(k).name)
            named[register(k).name] = v
        clear = named.pop("clear_unload", None)
        if clear is not None:
            check_id(servo_id)
            self.encode({"clear_unload": clear})  # range-checked before anything is sent
        runs = self.plan_write(servo_id, named) if named or clear is None else []
        # plan_write() puts the run with a new ID or baud last: the clear goes before it
        steps = [rv for _, rv in runs]
        if clear is not None:
            at = len(steps) - 1 if steps and ("id" in steps[-1] or "baud_rate" in
                                              steps[-1]) else len(steps)
            steps.insert(at, None)
        before = [self._before(servo_id, rv) if rv and len(runs) > 1 else {}
                  for rv in steps]
        waits, confirmed = [], True
        for i, rv in enumerate(steps):
            if rv is None:  # the clear: retried alone, never undone, nothing undone for it
                if clear == 1:
                    self._clear_after(servo_id, steps[:i])
                else:
                    self.write(servo_id, "clear_unload", clear)
                confirmed = confirmed and self.confirmed
                continue
            sent = None
            try:
                self._unchanged = self._same_eeprom(servo_id, rv)
                sent = self.packets_sent  # the WRITE is write()'s first packet
                self.write(servo_id, rv, check_variant=False)
            except Interrupted as e:  # a STOP goes through every check: say what is in
                # (a WRITE that went out is in force, its answer cut short or not)
                upto = i + 1 if sent is not None and self.packets_sent > sent else i
                e.written = {k: v for done in steps[:upto] if done for k, v in done.items()}
                e.unwritten = {k: v for rest in steps[upto:] if rest
                               for k, v in rest.items()}
                if clear is not None and None in steps[upto:]:
                    e.unwritten["clear_unload"] = clear
                raise
            except ServoBusError:
                self._write_back(servo_id, before[:i])
                raise
            finally:
                self._unchanged = False
            waits.append(self.commit_wait)
            confirmed = confirmed and self.confirmed
        known = [w for w in waits if w is not None]
        self.commit_wait = max(known) if known else None  # the longest of the WRITEs
        self.confirmed = confirmed
        return runs

    def _clear_after(self, servo_id, written):
        """clear_unload() after the settings of `written`; if it is refused for good,
        the refusal says that those settings were written and stay."""
        try:
            self.clear_unload(servo_id)
        except InstructionError as e:
            kept = ["%s=%s" % kv for rv in written for kv in rv.items()]
            if not kept:
                raise
            raise InstructionError(e.servo_id, e.err, e.what, "%s; %s %s written and stay" % (
                e.hint, ", ".join(kept), "was" if len(kept) == 1 else "were")) from None

    def _before(self, servo_id, rv):
        """What the readable registers of a run hold now (to write them back)."""
        readable = [n for n in rv if register(n).readable and n not in _NO_READBACK]
        return self.read_many(servo_id, readable) if readable else {}

    def _write_back(self, servo_id, befores):
        """Best effort: the runs written before a refused one get their old values."""
        for old in befores:
            if old:
                try:
                    self.write(servo_id, old, check_variant=False)
                except Interrupted:  # a STOP goes through every check
                    raise
                except ServoBusError:
                    pass

    def _same_eeprom(self, servo_id, rv):
        """True if every register of rv is EEPROM and already holds its value: the WRITE
        costs no flash commit (docs/persistence.md). False when unsure."""
        if not all(register(n).area == "EEPROM" and register(n).readable for n in rv):
            return False
        try:
            return self.read_many(servo_id, list(rv)) == dict(rv)
        except Interrupted:  # a STOP goes through every check
            raise
        except ServoBusError:
            return False

    def write_raw(self, servo_id, address, data):
        """WRITE raw bytes at address (no checks in the SDK; the servo validates)."""
        V.strict_integer(address, "address", 0, 0xFF)
        data = V.data(data, "data")
        self.transact(servo_id, P.WRITE, bytes([address]) + bytes(data),
                      "WRITE %d bytes at %d" % (len(data), address), hint=_WRITE_HINT)

    def reg_write(self, servo_id, reg, value=None):
        """REG WRITE: validated and held until ACTION (register 44 reads 1 meanwhile)."""
        regs_values = reg if isinstance(reg, dict) else {register(reg).name: value}
        check_id(servo_id, broadcast=True)
        variant = self.variant(servo_id) if servo_id != P.BROADCAST else None
        address, data = self.encode(regs_values, variant)
        self.transact(servo_id, P.REG_WRITE, bytes([address]) + data, "REG WRITE",
                      hint=_WRITE_HINT)
        # Held until ACTION, which commits it (a later REG WRITE replaces it).
        self._held_eeprom[servo_id] = _touches_eeprom(regs_values)

    def action(self, servo_id=P.BROADCAST):
        """ACTION: apply the held REG WRITE (broadcast by default: all at once)."""
        self.transact(servo_id, P.ACTION, what="ACTION",
                      hint="nothing was held by a REG WRITE, or the held write is refused now")
        if P.ACTION not in P.COMMITS:
            return
        everyone = servo_id == P.BROADCAST or self._held_eeprom.get(P.BROADCAST)
        held = list(self._held_eeprom) if everyone else [servo_id]
        for k in held:
            if k != P.BROADCAST and self._held_eeprom.get(k):
                self.commit_wait = self.commit_budget.commit(self.budget_key(k))
        if servo_id == P.BROADCAST:
            self._held_eeprom.clear()
        else:
            self._held_eeprom.pop(servo_id, None)

    def sync_write(self, reg, values):
        """SYNC WRITE (broadcast, no answers): values maps ID -> value, or ID -> dict of
        contiguous registers. Every value is range-checked before anything is sent."""
        slices = []
        address = length = None
        V.mapping(values, "SYNC WRITE values")
        for servo_id in values:
            V.servo_id(servo_id, "SYNC WRITE: ID", strict=True)
        for servo_id, v in sorted(values.items()):
            a, data = self.encode(v if isinstance(v, dict) else {register(reg).name: v})
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
        if P.SYNC_WRITE in P.COMMITS:  # each listed servo commits its slice
            for servo_id, v in sorted(values.items()):
                if _touches_eeprom(v if isinstance(v, dict) else {reg: v}):
                    self.commit_wait = self.commit_budget.commit(self.budget_key(servo_id))

    def dump(self, servo_id):
        """The whole table in one READ: a list of (Register, value or None where the
        register is not applicable/readable on this variant). One READ, its whole answer
        window listened to: two servos at the ID raise DuplicateId (read_alone)."""
        data = self.read_alone(servo_id, 0, TABLE_SIZE)
        variant = variant_by_model(int.from_bytes(data[0:2], "little"))
        self._variants[servo_id] = variant
        out = []
        for r in REGISTERS.values():
            if not r.applies_to(variant) or not r.readable:
                out.append((r, None))
                continue
            raw = int.from_bytes(data[r.address:r.address + r.size], "little")
            out.append((r, r.decode(raw)))
        return out


def _check_span(address, count):
    """RangeError unless address and count are ints inside the table."""
    V.strict_integer(address, "address")
    V.strict_integer(count, "count")
    if not (0 <= address < TABLE_SIZE and 1 <= count <= TABLE_SIZE - address):
        raise RangeError("READ %d bytes from %d is outside the table (addresses 0-%d)"
                         % (count, address, TABLE_SIZE - 1))
