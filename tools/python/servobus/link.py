"""Transport and transactions: one host on one servo bus, the instruction sent and the
status packet that answers it, and discovery (PING, broadcast PING scan)."""

import time
from collections import namedtuple

from . import protocol as P
from .errors import BusTimeout, ProtocolError, RangeError, ServoBusError, status_error
from .registers import BAUD_RATES
from .transport import open_transport

Found = namedtuple("Found", "id baud err")

_MOTION_HINT = ("the servo cannot run this motion now — firmware without motion support, "
                "no homing reference yet (home it, or see register 49 "
                "move_without_reference), a latched protection unload (write 1 to "
                "register 25 clear_unload), or speed mode")
# What a CAN (0x18) answer to each update step means (src/update.c).


class Link:
    """The transactions of a Bus (see servobus.bus.Bus for the constructor's arguments)."""

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

