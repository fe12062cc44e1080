"""The Bus: one host on one servo bus (a serial port or servo-sim over TCP)."""

import sys
import time
from collections import namedtuple

from . import image as I
from . import protocol as P
from .errors import (BusTimeout, IdTaken, ProtocolError, RangeError, ServoBusError,
                     UpdateError, UpdateRefused, UpdateTimeout, status_error)
from .registers import (BAUD_RATES, REGISTERS, TABLE_SIZE, register, variant_by_model)
from .transport import open_transport

Found = namedtuple("Found", "id baud err")
UpdateStats = namedtuple("UpdateStats",
                         "frames resent bytes_out bytes_in transfer_s restart_s")
HomingStatus = namedtuple("HomingStatus", "requested state text")

HOMING_STATES = {0: "never run", 1: "running", 2: "done", 3: "failed or aborted"}

_MOTION_HINT = ("the servo cannot run this motion now — firmware without motion support, "
                "no homing reference yet (home it, or see register 49 "
                "move_without_reference), a latched protection unload (write 1 to "
                "register 25 clear_unload), or speed mode")
# What a CAN (0x18) answer to each update step means (src/update.c).
_CAN_REASONS = {
    "enter": "it cannot start an update now",
    "header block": "the image length does not fit its application slot (%d..%d bytes)" % (
        I.MIN_BYTES, I.MAX_BYTES),
    "data block 1": "the image's info block is not for this servo (another model, or a "
                    "length that differs from the header block), or a flash error",
    "data block": "a flash error, or more blocks than the header block announced",
    "end of file": "fewer blocks arrived than the header block announced (truncated image)",
    "end of batch": "the image it received failed its check (CRC-32, model or length: a "
                    "corrupt or truncated image)",
}
# Time the servo may spend on an update frame before answering: erase, program and read
# back a 1 KiB flash page; the CRC-32 of the whole image at the end of the batch.
UPDATE_WORK_S = 0.2
# After the end of batch: seconds to wait for the restarted servo (the bootloader copies
# the image, up to 26 pages, before starting it).
RESTART_TIMEOUT_S = 10.0

_WRITE_HINT = ("a value out of range, a read-only, reserved or not-applicable register, "
               "a CW limit above the CCW limit, or a motion command the servo refuses now")


class Bus:
    """A servo bus.

    Bus('tcp://127.0.0.1:4242') talks to servo-sim; Bus('/dev/ttyUSB0', baud=115200) to
    a USB-RS485 adapter (pyserial). `timeout` (seconds) overrides the answer time-out
    computed from the baud rate. With raise_faults=False, live fault bits (temperature,
    current, voltage, stall) in an answer do not raise; they are kept in `faults`."""

    def __init__(self, port, baud=9600, timeout=None, raise_faults=True):
        self.port = port
        self.baud = baud
        self.timeout = timeout
        self.raise_faults = raise_faults
        self.faults = {}  # ID -> last ERR byte with a fault bit
        self.last_err = 0  # ERR byte of the last answer
        self.scan_notes = []  # what the last scan noticed (garbled answers...)
        self._variants = {}
        self.update_stats = None  # UpdateStats of the last update()
        self._ustats = [0, 0, 0, 0]
        self._t = open_transport(port, baud)

    # ---- plumbing -------------------------------------------------------------------

    def close(self):
        self._t.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    @property
    def is_tcp(self):
        return self._t.is_tcp

    def set_baud(self, baud):
        """Change the host side's baud rate (not the servos')."""
        if baud not in BAUD_RATES:
            raise RangeError("baud %s is not one of %s" % (baud, BAUD_RATES))
        self.baud = baud
        self._t.set_baud(baud)

    def answer_timeout(self, nbytes=7):
        """Seconds to wait for an answer of nbytes: the longest return delay, the bytes
        on the wire, and slack for the OS and USB adapters."""
        if self.timeout is not None:
            return self.timeout
        return P.MAX_RETURN_DELAY_S + nbytes * P.byte_time(self.baud) + 0.06

    def _where(self):
        return "at %d baud%s" % (self.baud, " on %s" % self.port if self.is_tcp else "")

    def send(self, servo_id, ins, params=b""):
        """Put one instruction packet on the bus (input is flushed first)."""
        pkt = P.instruction(servo_id, ins, params)
        self._t.flush_input()
        self._t.write(pkt)
        return pkt

    def receive(self, servo_id, sent, nbytes, what):
        """The status packet from servo_id answering `sent` (an exact echo of `sent`, as
        some adapters give, is skipped)."""
        parser = P.StatusParser()
        deadline = time.monotonic() + self.answer_timeout(nbytes)
        corrupt = None
        while True:
            data = self._t.read(deadline)
            if not data and time.monotonic() >= deadline:
                break
            for pkt in parser.feed(data):
                if pkt.raw == sent:
                    continue
                if not pkt.ok:
                    corrupt = pkt
                    continue
                if pkt.id == servo_id:
                    return pkt
        if corrupt is not None:
            raise ProtocolError(
                "corrupt status packet from ID %d %s (%s, bad checksum) — noise, a baud "
                "mismatch, or two servos with one ID?" % (servo_id, self._where(),
                                                          corrupt.raw.hex(" ")))
        if parser.pending():
            raise BusTimeout(
                "incomplete status packet from ID %d %s (%d bytes: %s) — baud mismatch or "
                "noise?" % (servo_id, self._where(), parser.pending(),
                            bytes(parser.buf).hex(" ")), servo_id)
        hint = "wrong ID or baud? try `servoctl scan --all-bauds`"
        if what.split()[0] not in ("PING", "READ"):
            hint += "; or the servo's status return level (register 16) is below 2"
        raise BusTimeout("no status packet from ID %d %s (%s) — %s" % (
            servo_id, self._where(), what, hint), servo_id)

    def transact(self, servo_id, ins, params=b"", what=None, nbytes=7, motion=False,
                 hint=""):
        """Send an instruction; for a single ID wait for its answer and raise on ERR bits.
        Returns the StatusPacket, or None for broadcast."""
        what = what or P.INSTRUCTION_NAMES.get(ins, "instruction 0x%02X" % ins)
        sent = self.send(servo_id, ins, params)
        if servo_id == P.BROADCAST:
            return None
        pkt = self.receive(servo_id, sent, nbytes, what)
        err = pkt.ping_err() if ins == P.PING else pkt.err
        self.last_err = err
        self._check(servo_id, err, what, hint or (_MOTION_HINT if motion else ""),
                    pkt.params, motion)
        return pkt

    def _check(self, servo_id, err, what, hint, params, motion):
        if err & P.ERR_FAULTS:
            self.faults[servo_id] = err
        if err & (P.ERR_INSTRUCTION | P.ERR_CHECKSUM) or (
                err & P.ERR_FAULTS and self.raise_faults):
            raise status_error(servo_id, err, what, hint, params, motion)

    # ---- discovery ------------------------------------------------------------------

    def ping(self, servo_id):
        """PING one servo. Returns its live ERR byte (0 = healthy); BusTimeout if absent."""
        pkt = self.transact(servo_id, P.PING, what="PING")
        return pkt.ping_err()

    def present(self, servo_id, timeout=None):
        """True if servo_id answers a PING."""
        saved = self.timeout
        if timeout is not None:
            self.timeout = timeout
        try:
            self.ping(servo_id)
            return True
        except BusTimeout:
            return False
        except ServoBusError:
            return True  # it answered, if with an error
        finally:
            self.timeout = saved

    def scan_window(self, baud=None):
        """Seconds a broadcast PING's answers take: the longest return delay plus one
        answer slot per ID 0-253 (§4.1), plus slack."""
        baud = baud or self.baud
        return (P.MAX_RETURN_DELAY_S + (P.ID_MAX + 1) * P.SLOT_BYTES * P.byte_time(baud) +
                7 * P.byte_time(baud) + 0.06)

    def scan(self, all_bauds=False):
        """Broadcast PING (ID-slotted answers, §4.1) at the bus baud, or at every baud of
        §5.2 with all_bauds. Returns a list of Found(id, baud, err) sorted by ID. Over
        tcp:// the simulator hears every baud, so all_bauds scans once (harmless)."""
        self.scan_notes = []
        bauds = [self.baud]
        if all_bauds and self.is_tcp:
            self.scan_notes.append("over tcp:// every servo hears the host whatever its "
                                   "baud, so --all-bauds scans once")
        elif all_bauds:
            bauds = list(BAUD_RATES)
        found = {}
        start_baud = self.baud
        try:
            for baud in bauds:
                if baud != self.baud:
                    self.set_baud(baud)
                for f in self._scan_once():
                    found.setdefault(f.id, f)
        finally:
            if self.baud != start_baud:
                self.set_baud(start_baud)
        return [found[i] for i in sorted(found)]

    def _scan_once(self):
        sent = self.send(P.BROADCAST, P.PING)
        parser = P.StatusParser()
        deadline = time.monotonic() + self.scan_window()
        out = []
        while time.monotonic() < deadline:
            for pkt in parser.feed(self._t.read(deadline)):
                if pkt.raw == sent:
                    continue
                if not pkt.ok or len(pkt.params) != 1 or pkt.err != 0x01:
                    self.scan_notes.append("a garbled answer at %d baud (%s): two servos "
                                           "with one ID?" % (self.baud, pkt.raw.hex(" ")))
                    continue
                out.append(Found(pkt.id, self.baud, pkt.params[0]))
        return out

    # ---- the control table ----------------------------------------------------------

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

    # ---- motion ---------------------------------------------------------------------

    def position_register(self, servo_id):
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

    def brake(self, servo_id, on=True):
        self.write(servo_id, "brake", 1 if on else 0)

    def start_end(self, servo_id, what):
        """START/END: 'start' makes the present position 0 and the CW limit; 'end' makes
        it the CCW limit."""
        code = {"start": 1, "end": 2}.get(what, what)
        self.transact(servo_id, P.START_END, bytes([code]), "START/END %s" % what,
                      motion=True)

    def trajectory_write(self, servo_id, points, point_size=None):
        """TRAJECTORY WRITE of [(angle, speed), ...] (position units, units/s; speed > 0).
        The 4-byte point form is used when it fits (63 points), else the 3-byte form
        (speeds up to 255, 84 points). An empty list clears the stored trajectory."""
        points = [(int(a), int(s)) for a, s in points]
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
        return self._custom(servo_id, 0x01, abs(delta), (0x8000 if delta < 0 else 0) |
                            abs(speed), acc, dec, "CUSTOM MOVE relative %+d" % delta)

    def move_absolute(self, servo_id, position, speed, acc=36, dec=36):
        """CUSTOM MOVE sub 2: absolute move to position at speed with ramps."""
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
                if not 0 <= v <= 255:
                    raise RangeError("%s: %s %d is out of range 0..255" % (what, name, v))
            params += bytes([acc, dec])
        self.transact(servo_id, P.CUSTOM, params, what, motion=True)

    # ---- homing ---------------------------------------------------------------------

    def home(self, servo_id):
        """Start homing (register 24 = 1); see homing_status()/wait_homed()."""
        self.write(servo_id, "homing", 1)

    def stop_homing(self, servo_id):
        self.write(servo_id, "homing", 0)

    def homing_status(self, servo_id):
        """HomingStatus(requested, state, text) from register 24 (low nibble as written,
        high nibble 0 never, 1 running, 2 done, 3 failed)."""
        raw = self.read(servo_id, "homing")
        state = raw >> 4
        return HomingStatus(raw & 0x0F, state, HOMING_STATES.get(state, "state %d" % state))

    def wait_homed(self, servo_id, timeout=30.0, poll=0.1):
        """Wait until homing is done; raise ServoBusError if it failed or timed out."""
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
                        " — this firmware does not run homing yet" if st.state == 0 else ""))
            time.sleep(poll)

    # ---- firmware update (§10) ------------------------------------------------------

    def update_timeout(self, frame_bytes):
        """Seconds to wait for the answer to an update frame of frame_bytes: the frame and
        its answer on the wire, the longest return delay, the servo's flash work, slack.
        Bus(timeout=...) overrides it."""
        if self.timeout is not None:
            return self.timeout
        return (P.MAX_RETURN_DELAY_S + (frame_bytes + P.UPDATE_ANSWER_BYTES) *
                P.byte_time(self.baud) + UPDATE_WORK_S + 0.06)

    def update(self, servo_id, image, progress=None, retries=5, check=True,
               restart_timeout=RESTART_TIMEOUT_S, notify=None):
        """Send a firmware image to servo_id over the bus (PROTOCOL.md §10) and return the
        firmware version (register 2) the servo reports after restarting into it.

        image: the bytes of a stamped image (tools/fwstamp.py). With check (default) it is
        validated first (magic, length, CRC-32, size: ImageError, nothing sent), and if
        the servo answers PING its model number must match the image's (ImageError). A
        servo that does not answer PING may be in its bootloader, which answers only the
        update frames: the update goes ahead (notify says so). check=False sends the
        bytes as they are (the servo then makes its own checks).

        progress(blocks_done, blocks_total, bytes_done, bytes_total) is called before the
        first data block and after each one. A frame that is not answered in time
        (update_timeout) or answered NAK is sent again, `retries` times at most
        (UpdateTimeout, UpdateError). A CAN answer raises UpdateRefused: the servo
        abandoned the update and runs its old firmware. notify(text) receives notes
        (default: printed on stderr). Afterwards `update_stats` holds an UpdateStats:
        frames sent (resent: how many were repeats), bytes_out (frames, repeats
        included), bytes_in (the answers taken), transfer_s (enter to the end-of-batch
        answer) and restart_s (from there to the version read)."""
        image = bytes(image)
        if notify is None:
            def notify(text):
                print("servobus: note: " + text, file=sys.stderr)
        expect_version = None
        if check:
            info = I.validate(image)
            if self.present(servo_id) or self.present(servo_id):  # a lost PING: once more
                I.validate(image, self.read(servo_id, "model_number"))
            else:
                notify("ID %d does not answer PING at %d baud: assuming it waits in its "
                       "bootloader (update mode answers only update frames) and updating "
                       "it without checking its model" % (servo_id, self.baud))
            expect_version = info.version
        else:
            try:
                expect_version = I.parse(image).version
            except I.ImageError:
                pass
        frames = P.update_frames(servo_id, image)
        blocks = sum(1 for step, _, _ in frames if step.startswith("data block"))
        done = sent = 0
        self._ustats = [0, 0, 0, 0]  # frames, resent, bytes out, bytes in
        self.update_stats = None
        if progress:
            progress(0, blocks, 0, len(image))
        t0 = time.monotonic()
        for step, frame, nbytes in frames:
            self._update_step(servo_id, step, frame, retries)
            if nbytes:
                done += 1
                sent += nbytes
                if progress:
                    progress(done, blocks, sent, len(image))
        t1 = time.monotonic()
        self._variants.pop(servo_id, None)
        version = self._await_restart(servo_id, restart_timeout, expect_version)
        self.update_stats = UpdateStats(*self._ustats, transfer_s=t1 - t0,
                                        restart_s=time.monotonic() - t1)
        return version

    def _update_step(self, servo_id, step, frame, retries):
        """Send one update frame until it is answered with the expected code: the
        StatusPacket. NAK or silence: send again, retries times at most."""
        expect = P.READY if step == "enter" else P.ACK
        naks = silent = 0
        last = ""
        for attempt in range(retries + 1):
            self._t.flush_input()
            self._t.write(frame)
            self._ustats[0] += 1
            self._ustats[1] += attempt > 0
            self._ustats[2] += len(frame)
            pkt, why = self._update_answer(servo_id, frame)
            if pkt is None:
                silent += 1
                last = why
                continue
            code = pkt.params[0] if pkt.params else None
            if pkt.err & P.ERR_INSTRUCTION:
                raise UpdateError(
                    "ID %d answered the %s with an instruction error (%s): its firmware "
                    "does not take updates over the bus (§10)" % (
                        servo_id, "request to enter update mode" if step == "enter" else step,
                        pkt.raw.hex(" ")), servo_id, step)
            if code == expect:
                self._ustats[3] += len(pkt.raw)
                return pkt
            if code == P.CAN:
                reason = _CAN_REASONS.get(step) or _CAN_REASONS["data block"]
                raise UpdateRefused(
                    "ID %d refused the update at the %s (CAN): %s; it keeps its running "
                    "firmware" % (servo_id, step, reason), servo_id, step)
            naks += 1
            last = ("NAK" if code == P.NAK else
                    "a checksum error" if pkt.err & P.ERR_CHECKSUM else
                    "an unexpected answer (%s)" % pkt.raw.hex(" "))
        tries = retries + 1
        if not naks:
            hint = ("wrong ID or baud, or the servo is not on the bus" if step == "enter"
                    else "the servo stopped answering (power, wiring?); it abandons a "
                         "silent update after 10 s and keeps its running firmware — start "
                         "the update again")
            raise UpdateTimeout("no answer from ID %d %s to the %s after %d tries (%s) — %s"
                                % (servo_id, self._where(), step, tries, last, hint),
                                servo_id, step)
        raise UpdateError(
            "ID %d %s: the %s failed %d times (%d NAK or damaged answers, %d silent; last: "
            "%s) — noise on the wire: check wiring, termination (register 20) and the baud "
            "rate" % (servo_id, self._where(), step, tries, naks, silent, last),
            servo_id, step)

    def _update_answer(self, servo_id, sent):
        """(StatusPacket, None) for the first intact answer from servo_id to the update
        frame `sent`, or (None, why) at the time-out. An adapter's echo of `sent` is
        dropped (the echo of a data block would not parse as a status packet)."""
        parser = P.StatusParser()
        deadline = time.monotonic() + self.update_timeout(len(sent))
        echo = bytearray()  # what arrived while it could still be the echo of `sent`
        in_echo = True
        corrupt = None
        while True:
            data = self._t.read(deadline)
            if not data:
                if time.monotonic() >= deadline:
                    break
                continue
            if in_echo:
                echo += data
                if sent.startswith(bytes(echo)):
                    if len(echo) == len(sent):
                        in_echo = False
                    continue
                in_echo = False
                data = bytes(echo[len(sent):] if echo.startswith(sent) else echo)
            for pkt in parser.feed(data):
                if pkt.raw == sent:
                    continue
                if not pkt.ok:
                    corrupt = pkt
                elif pkt.id == servo_id:
                    return pkt, None
        if corrupt is not None:
            return None, "a corrupt answer: %s" % corrupt.raw.hex(" ")
        if parser.pending():
            return None, "an incomplete answer: %s" % bytes(parser.buf).hex(" ")
        return None, "no answer within %.0f ms" % (self.update_timeout(len(sent)) * 1e3)

    def _await_restart(self, servo_id, timeout, expect_version):
        """After the end of batch: poll PING until the restarted servo answers, then its
        firmware version (register 2); until it is expect_version if that is known."""
        deadline = time.monotonic() + timeout
        time.sleep(0.02)  # the servo restarts once its last answer is out
        version = None
        while True:
            try:
                if self.present(servo_id):
                    version = self.read(servo_id, "firmware_version")
                    if expect_version is None or version == expect_version:
                        return version
            except ServoBusError:
                pass
            if time.monotonic() > deadline:
                break
            time.sleep(0.05)
        if version is None:
            raise UpdateError(
                "ID %d took the image but does not answer PING %.0f s later: it may still "
                "be installing it, or be waiting in its bootloader (update mode) — PING it "
                "again later, or repeat the update" % (servo_id, timeout), servo_id,
                "restart")
        raise UpdateError(
            "ID %d took the image but restarted with firmware version %d, not the image's "
            "%d: its bootloader did not install it" % (servo_id, version, expect_version),
            servo_id, "restart")
