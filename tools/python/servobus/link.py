"""Transport and transactions: one host on one servo bus, the instruction sent and the
status packet that answers it, and discovery (PING, broadcast PING scan, two servos on
one ID, a servo waiting in its bootloader).

Every answer is matched to its request: it must come from the ID addressed, have the
shape of that instruction's answer (PING `03 01 ERR`, a READ's exact length, no
parameters otherwise), and arrive after the request; bytes that may still be on their
way from an earlier request (one that timed out) are waited for and dropped before the
next request goes out."""

import math
import time
from collections import namedtuple

from . import protocol as P
from . import values as V
from .errors import (BusTimeout, Interrupted, ProtocolError, RangeError, ServoBusError,
                     ServoFault, status_error)
from .budget import CommitBudget
from .registers import BAUD_RATES
from .transport import open_transport

Found = namedtuple("Found", "id baud err")

# An open update session (§10) refuses everything but PING and READ for 10 s after its
# last frame (src/dispatch.c): a refusal hint names it.
SESSION_HINT = "an update session still open (it ends 10 s after the last update frame)"
_MOTION_HINT = ("the servo cannot run this motion now — no homing reference yet (home "
                "it, or see register 49 move_without_reference), a latched protection "
                "unload (write 1 to register 25 clear_unload), speed mode, or " +
                SESSION_HINT)
SLACK_S = 0.06
TCP_SLACK_S = 0.14
# Seconds a Bus(timeout=...) may be: more than 0, at most an hour.
TIMEOUT_RANGE = (0.001, 3600.0)
# With a stop_event, every wait looks at it this often: a STOP is seen within 10 ms.
STOP_POLL_S = 0.01


def check_id(servo_id, broadcast=False):
    """RangeError unless servo_id is an int 0-253 (or 254, broadcast, where allowed)."""
    V.servo_id(servo_id, broadcast=broadcast, strict=True)


def answer_shape(ins, params=b""):
    """A predicate: is this status packet shaped as the answer to `ins`? PING:
    `LEN 3, 01, ERR`; READ of n bytes: n parameters; everything else none. An error
    answer (ERR bit 4 or 5) has no parameters whatever the instruction."""
    if ins == P.PING:
        return lambda pkt: len(pkt.params) == 1 and pkt.err == 0x01
    count = params[1] if ins == P.READ and len(params) >= 2 else 0

    def shaped(pkt):
        if pkt.err & (P.ERR_INSTRUCTION | P.ERR_CHECKSUM) and not pkt.params:
            return True
        return len(pkt.params) == count
    return shaped


class Link:
    """The transactions of a Bus (see servobus.bus.Bus for the constructor's arguments)."""

    def __init__(self, port, baud=9600, timeout=None, raise_faults=True):
        if not isinstance(port, str) or not port:
            raise RangeError("port %r: give tcp://HOST:PORT or a serial device" % (port,))
        if baud not in BAUD_RATES:
            raise RangeError("baud %s is not one of %s" % (baud, BAUD_RATES))
        if timeout is not None:
            if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or \
                    not math.isfinite(timeout) or \
                    not TIMEOUT_RANGE[0] <= timeout <= TIMEOUT_RANGE[1]:
                raise RangeError("timeout %r: give seconds, %g to %g" % (
                    timeout, TIMEOUT_RANGE[0], TIMEOUT_RANGE[1]))
        self.port = port
        self.baud = baud
        self.timeout = timeout
        self.raise_faults = raise_faults
        self.faults = {}  # ID -> last ERR byte with a fault bit
        self.last_err = 0  # ERR byte of the last answer
        self.scan_notes = []  # what the last scan noticed (garbled answers...)
        self.duplicates = []  # IDs the last scan found two servos at
        self.confirmed = True  # False: the last instruction went out unanswered (level 0)
        self._variants = {}
        self._levels = {}  # ID -> status return level (register 16) once found below 2
        self._quiet_at = 0.0  # a late answer may arrive until then: drain before sending
        self._sent_at = 0.0  # when the last request went out
        self._on_wire_until = 0.0  # when the bytes written so far have left the wire
        self.update_stats = None  # UpdateStats of the last update()
        self.update_step = None  # the §10 step under way (what an interrupt cuts short)
        self.update_mode = False  # the last update() found the servo in update mode
        self._ustats = [0, 0, 0, 0]
        # Estimated flash commit budget of each servo (budget.py); servoctl gives it a
        # state file. commit_wait: seconds the last EEPROM write may wait for flash.
        self.commit_budget = CommitBudget()
        self.commit_wait = None
        # A threading.Event (or None): once set, every wait and every packet about to be
        # sent is cut short with Interrupted, at a packet boundary (Servo Studio's STOP).
        self.stop_event = None
        self._stop_seen = None  # when a wait first saw stop_event set
        self.packets_sent = 0  # every packet this Bus put on the wire
        # A function tap(direction, bytes, time.monotonic()) or None: every packet sent
        # ("tx") and every chunk of bytes received ("rx"), for a wire console.
        self.tap = None
        self._t = open_transport(port, baud)

    def budget_key(self, servo_id):
        """The commit budget's key for a servo on this port."""
        check_id(servo_id)
        return "%s#%d" % (self.port, servo_id)

    # ---- plumbing -------------------------------------------------------------------

    def close(self):
        """Close the port once what was written has left the wire, as a serial port's
        close drains its output: a broadcast's bytes (which nothing answers) are not cut
        off by a close right after them (servo-sim drops what a client that left had not
        yet delivered at its servos' baud)."""
        wait = self._on_wire_until - time.monotonic()
        if wait > 0:
            time.sleep(min(wait + self.slack(), 2.0))
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
        return self.full_answer_time(nbytes)

    def full_answer_time(self, nbytes=7):
        """The answer time-out computed from the baud rate, whatever Bus(timeout=)."""
        V.strict_integer(nbytes, "answer bytes", 0, 0x10000)
        return P.MAX_RETURN_DELAY_S + nbytes * P.byte_time(self.baud) + self.slack()

    def slack(self):
        """Seconds of slack in a time-out, for the OS and USB adapters; over a network
        port (tcp://, rfc2217://) more: servo-sim shares the host's CPU, and a busy
        host delays its answers."""
        shared = self.is_tcp or getattr(self._t, "remote", False)  # rfc2217:// too
        return SLACK_S + (TCP_SLACK_S if shared else 0.0)

    def _where(self):
        return "at %d baud%s" % (self.baud, " on %s" % self.port if self.is_tcp else "")

    def _drain(self):
        """Wait until no late answer to an earlier request can still arrive, then drop
        whatever has arrived: stale bytes are never taken for the next answer."""
        while time.monotonic() < self._quiet_at:
            self._read(self._quiet_at)
        self._t.flush_input()

    # ---- cut short by stop_event --------------------------------------------------

    def check_stop(self):
        """Interrupted if stop_event is set: called before every packet is sent."""
        if self.stop_event is not None and self.stop_event.is_set():
            raise Interrupted("cut short by STOP: nothing more was sent")

    def pause(self, seconds):
        """Sleep for seconds; with a stop_event, Interrupted as soon as it is set."""
        V.seconds(seconds, "pause", 0.0, 3600.0)
        if self.stop_event is None:
            time.sleep(seconds)
        elif self.stop_event.wait(seconds):
            raise Interrupted("cut short by STOP: nothing more was sent")

    def _read(self, deadline, parser=None):
        """Bytes that arrive before deadline (b'' if none). With a stop_event the wait
        is cut into STOP_POLL_S slices; once it is set, Interrupted — at a packet
        boundary: a packet already arriving (the parser holds its start) is read to its
        end first, at most its own time on the wire, so that nothing is sent into it."""
        if self.stop_event is None:
            return self._tapped(self._t.read(deadline))
        if not self.stop_event.is_set():
            self._stop_seen = None
        else:
            now = time.monotonic()
            if self._stop_seen is None:
                self._stop_seen = now
            if now >= self._stop_seen + self._rest_of_packet(parser):
                self._stop_seen = None
                raise Interrupted("cut short by STOP: nothing more was sent")
        return self._tapped(self._t.read(min(deadline, time.monotonic() + STOP_POLL_S)))

    def _tapped(self, data):
        if data and self.tap is not None:
            self.tap("rx", data, time.monotonic())
        return data

    def _rest_of_packet(self, parser):
        """Seconds until the packet the parser holds the start of has arrived: 0 when it
        holds none; LEN tells its length once its first 4 bytes are in."""
        held = parser.pending() if parser is not None else 0
        if not held:
            return 0.0
        total = parser.buf[3] + 4 if held >= 4 else 8
        return max(0, total - held) * P.byte_time(self.baud) + 0.02

    def _late_until(self, sent, nbytes):
        """After a request that went unanswered, an answer to it may still arrive until
        the longest return delay and its bytes have passed."""
        self._quiet_at = max(self._quiet_at, time.monotonic() + P.MAX_RETURN_DELAY_S +
                             (len(sent) + nbytes) * P.byte_time(self.baud) + self.slack())

    def send(self, servo_id, ins, params=b""):
        """Put one instruction packet on the bus (stale input is drained first)."""
        check_id(servo_id, broadcast=True)
        V.strict_integer(ins, "instruction", 0, 0xFF)
        params = V.data(params, "parameters")
        try:
            pkt = P.instruction(servo_id, ins, params)
        except ValueError as e:
            raise RangeError(str(e)) from None
        self._drain()
        self.check_stop()
        self._put(pkt)
        return pkt

    def _put(self, pkt):
        """Write one packet to the transport (counted in packets_sent)."""
        self._t.write(pkt)
        self.packets_sent += 1
        self._sent_at = time.monotonic()
        self._on_wire_until = max(self._on_wire_until, self._sent_at) + \
            len(pkt) * P.byte_time(self.baud)
        if self.tap is not None:
            self.tap("tx", bytes(pkt), self._sent_at)

    def receive(self, servo_id, sent, nbytes, what, shape=None):
        """The status packet from servo_id answering `sent` (an exact echo of `sent`, as
        some adapters give, is skipped; so is a packet not shaped as the answer)."""
        check_id(servo_id)
        what = str(what) or "the request"
        sent = V.data(sent, "the request sent")
        V.strict_integer(nbytes, "answer bytes", 0, 0x10000)
        if shape is not None and not callable(shape):
            raise RangeError("shape %r is not a function of a status packet" % (shape,))
        parser = P.StatusParser()
        deadline = time.monotonic() + self.answer_timeout(nbytes)
        corrupt = misshaped = None
        while True:
            try:
                data = self._read(deadline, parser)
            except Interrupted:
                self._late_until(sent, nbytes)  # its answer may still come: drained later
                raise
            if not data and time.monotonic() >= deadline:
                break
            for pkt in parser.feed(data):
                if pkt.raw == sent:
                    continue
                if not pkt.ok:
                    corrupt = pkt
                    continue
                if pkt.id == servo_id:
                    if shape is None or shape(pkt):
                        return pkt
                    misshaped = pkt
        self._late_until(sent, nbytes)
        if corrupt is not None or parser.skipped:
            raw = corrupt.raw if corrupt is not None else b""
            raise ProtocolError(
                "garbled answer from ID %d %s (%s) — two servos with one ID answering "
                "at once, noise, or a baud mismatch; `servoctl --id %d ping` tells two "
                "servos apart from noise" % (servo_id, self._where(),
                                             raw.hex(" ") or "bytes without a packet",
                                             servo_id))
        if parser.pending():
            raise BusTimeout(
                "incomplete status packet from ID %d %s (%d bytes: %s) — baud mismatch, "
                "noise, or two servos with one ID?" % (
                    servo_id, self._where(), parser.pending(),
                    bytes(parser.buf).hex(" ")), servo_id)
        if misshaped is not None:
            raise ProtocolError(
                "ID %d answered %s with a packet of another shape (%s): not its answer "
                "(a late answer to an earlier request?)" % (servo_id, what,
                                                            misshaped.raw.hex(" ")))
        hint = "wrong ID or baud? try `servoctl scan --all-bauds`"
        if what.split()[0] not in ("PING", "READ"):
            hint += "; or the servo's status return level (register 16) is below 2"
        raise BusTimeout("no status packet from ID %d %s (%s) — %s" % (
            servo_id, self._where(), what, hint), servo_id)

    def transact(self, servo_id, ins, params=b"", what=None, nbytes=7, motion=False,
                 hint=""):
        """Send an instruction; for a single ID wait for its answer and raise on ERR bits.
        Returns the StatusPacket, or None for broadcast and for an instruction sent to a
        servo whose status return level (register 16) keeps it silent (self.confirmed
        is then False: the caller verifies what it can)."""
        V.strict_integer(ins, "instruction", 0, 0xFF)
        V.strict_integer(nbytes, "answer bytes", 0, 0x10000)
        what = str(what or P.INSTRUCTION_NAMES.get(ins, "instruction 0x%02X" % ins))
        check_id(servo_id, broadcast=ins not in (P.PING, P.READ))
        self.confirmed = True
        silent = servo_id != P.BROADCAST and ins not in (P.PING, P.READ) and \
            self._levels.get(servo_id, 2) < 2
        sent = self.send(servo_id, ins, params)
        if servo_id == P.BROADCAST:
            return None
        if silent:
            self.confirmed = False
            self._late_until(sent, 0)  # the packet's own time on the wire
            return None
        try:
            pkt = self.receive(servo_id, sent, nbytes, what, answer_shape(ins, params))
        except BusTimeout as e:
            if ins == P.READ and self._levels.get(servo_id) != 1 and \
                    self.present(servo_id, timeout=self.full_answer_time()):
                pkt = self._read_again(servo_id, params, nbytes, what)
            elif ins == P.PING or self._levels.get(servo_id) == 1:
                raise
            elif ins == P.READ:
                raise self.silent(servo_id, e) from None  # absent, or in update mode
            else:
                return self._unanswered(servo_id, e)
        if ins == P.READ and self._levels.get(servo_id) == 0:
            del self._levels[servo_id]  # it answers READ: not level 0 (any more)
        err = pkt.ping_err() if ins == P.PING else pkt.err
        self.last_err = err
        self._check(servo_id, err, what, hint or (_MOTION_HINT if motion else ""),
                    pkt.params, motion)
        return pkt

    def _read_again(self, servo_id, params, nbytes, what):
        """A READ not answered by a servo that answers PING: one answer lost or late, or
        status return level 0. Once more; silent again, it is level 0 (BusTimeout)."""
        sent = self.send(servo_id, P.READ, params)
        saved, self.timeout = self.timeout, None
        try:
            return self.receive(servo_id, sent, nbytes, what, answer_shape(P.READ, params))
        except BusTimeout:
            self._levels[servo_id] = 0
            raise BusTimeout(
                "ID %d answers PING but not %s: its status return level (register 16) is "
                "0 — `servoctl --id %d set status_return_level 2` (bus.write(%d, "
                "'status_return_level', 2)) makes it answer again" % (
                    servo_id, what, servo_id, servo_id), servo_id) from None
        finally:
            self.timeout = saved

    def _unanswered(self, servo_id, e):
        """An instruction other than PING and READ not answered (BusTimeout e): None if
        register 16 keeps the servo silent (self.confirmed False), else e raised."""
        try:  # a servo that answers PING but not this: register 16 keeps it silent
            level = self.status_return_level(servo_id)
        except BusTimeout as absent:  # nothing answers: e, unless update mode is named
            raise absent if absent.update_mode else e from None
        if level >= 2:
            raise e
        self.confirmed = False
        return None

    def _check(self, servo_id, err, what, hint, params, motion):
        if err & P.ERR_FAULTS:
            self.faults[servo_id] = err
        if err & (P.ERR_INSTRUCTION | P.ERR_CHECKSUM) or (
                err & P.ERR_FAULTS and self.raise_faults):
            raise status_error(servo_id, err, what, hint, params, motion)

    def known_level(self, servo_id):
        """The status return level this Bus has found for servo_id (2 until it has seen
        the servo keep silent)."""
        check_id(servo_id)
        return self._levels.get(servo_id, 2)

    def status_return_level(self, servo_id):
        """Register 16 of a servo, found even at level 0 (where only PING is answered):
        READ it; if that is not answered but PING is, the level is 0. BusTimeout if the
        servo answers neither. The level is remembered, so that later instructions to a
        silent servo are sent without waiting for an answer that will not come."""
        check_id(servo_id)  # before the READ: a refused ID is not "level 2"
        saved, self.timeout = self.timeout, None  # not a short Bus(timeout=) here
        try:
            level = self.read_raw(servo_id, 16, 1)[0]
        except BusTimeout:
            if self._levels.get(servo_id) != 0:  # the READ's time-out PINGed it: absent
                raise
            level = 0
        except ServoFault as e:  # a live fault bit: the answer is there all the same
            level = e.params[0] if len(e.params) == 1 else 2
        except Interrupted:  # a STOP goes through every check
            raise
        except ServoBusError:
            return 2
        finally:
            self.timeout = saved
        if level < 2:
            self._levels[servo_id] = level
        else:
            self._levels.pop(servo_id, None)
        return level

    # ---- discovery ------------------------------------------------------------------

    def ping(self, servo_id):
        """PING one servo. Returns its live ERR byte (0 = healthy); BusTimeout if absent
        (saying so if it waits in its bootloader's update mode)."""
        try:
            pkt = self.transact(servo_id, P.PING, what="PING")
        except BusTimeout as e:
            raise self.silent(servo_id, e) from None
        return pkt.ping_err()

    def present(self, servo_id, timeout=None):
        """True if servo_id answers a PING (within timeout seconds, if given)."""
        check_id(servo_id)
        if timeout is not None:
            V.seconds(timeout, "time-out", TIMEOUT_RANGE[0], TIMEOUT_RANGE[1])
        saved = self.timeout
        if timeout is not None:
            self.timeout = timeout
        try:
            self.transact(servo_id, P.PING, what="PING")  # not ping(): no update-mode check
            return True
        except BusTimeout:
            return False
        except Interrupted:  # a STOP goes through every check
            raise
        except ServoBusError:
            return True  # it answered, if with an error or garbled (two servos?)
        finally:
            self.timeout = saved
