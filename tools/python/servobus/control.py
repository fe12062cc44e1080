"""The control table over the bus: READ, WRITE, REG WRITE/ACTION, SYNC WRITE, the whole
table, the ID and a factory reset."""

from . import protocol as P
from .errors import IdTaken, ProtocolError, RangeError
from .link import _MOTION_HINT
from .registers import REGISTERS, TABLE_SIZE, register, variant_by_model

_WRITE_HINT = ("a value out of range, a read-only, reserved or not-applicable register, "
               "a CW limit above the CCW limit, or a motion command the servo refuses now")


class Control:
    """Register access (a mixin of Bus: it uses Link's transactions)."""

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
        """The servo's variant (from its model number; cached per ID), or None."""
        if servo_id not in self._variants:
            self._variants[servo_id] = variant_by_model(self.read(servo_id, "model_number"))
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
        variant = self.variant(servo_id) if check_variant and servo_id != P.BROADCAST else None
        address, data = self.encode(regs_values, variant)
        names = ", ".join("%s=%s" % (register(k).name, v) for k, v in regs_values.items())
        motion = any(register(k).name in ("goal_position", "moving_speed", "homing")
                     for k in regs_values)
        self.transact(servo_id, P.WRITE, bytes([address]) + data, "WRITE " + names,
                      hint=_MOTION_HINT if motion else _WRITE_HINT, motion=motion)
        if any(register(k).name == "id" for k in regs_values):
            self._variants.pop(servo_id, None)

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

    def set_id(self, servo_id, new_id, check_free=True):
        """Give servo_id the ID new_id. Refuses (IdTaken) if another servo answers at
        new_id. The answer comes from the old ID; afterwards the servo answers at the new."""
        if not 0 <= new_id <= P.ID_MAX:
            raise RangeError("ID %d is out of range 0..253" % new_id)
        if new_id == servo_id:
            return
        self.ping(servo_id)  # the servo to change must be there
        if check_free and self.present(new_id):
            raise IdTaken("ID %d is already taken on the bus (a servo answered a PING "
                          "there); choose another ID or move that servo first" % new_id)
        self.write(servo_id, "id", new_id, check_variant=False)
        self._variants.pop(servo_id, None)

    def reset(self, servo_id):
        """RESET to factory values (ID 1, default baud...); answered with the old ID."""
        self.transact(servo_id, P.RESET, what="RESET")
        self._variants.clear()

