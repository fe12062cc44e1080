"""Discovery on the bus: the broadcast PING scan (§4.1), two servos on one ID, and a
servo waiting in its bootloader's update mode."""

import time

from . import protocol as P
from . import values as V
from .errors import BusTimeout, Interrupted, RangeError, ServoBusError
from .link import Found, answer_shape, check_id
from .registers import BAUD_RATES, TABLE_SIZE, baud_of_code, variant_by_model

IN_UPDATE_MODE = ("it waits in its bootloader's update mode (its application is damaged, "
                  "or a new image did not confirm itself within 3 starts)")


class Discovery:
    """Who is on the bus (a mixin of Bus: it uses Link's transport and transactions)."""

    def listen(self, servo_id, frame, shape, nbytes=16):
        """Send a raw frame to servo_id and listen for the whole answer window (the
        longest return delay and an answer of nbytes): (intact answers from servo_id
        shaped as `shape` wants, garbled: whether bytes arrived that are not such an
        answer). Intact packets of another shape are left out: they answer something
        else."""
        check_id(servo_id)
        frame = V.data(frame, "frame")
        V.strict_integer(nbytes, "answer bytes", 0, 0x10000)
        if not callable(shape):
            raise RangeError("shape %r is not a function of a status packet" % (shape,))
        # A second servo at the ID of the last request may still be answering it: wait
        # its window out (a request sent into an answer would collide on the wire).
        self._quiet_at = max(self._quiet_at,
                             self._sent_at + self.full_answer_time(6 + TABLE_SIZE))
        self._drain()
        self.check_stop()
        self._put(frame)
        parser = P.StatusParser()
        deadline = time.monotonic() + self.full_answer_time(nbytes)
        answers, garbled = [], False
        while time.monotonic() < deadline:
            try:
                data = self._read(deadline, parser)
            except Interrupted:
                self._quiet_at = max(self._quiet_at, deadline)  # answers may still come
                raise
            for pkt in parser.feed(data):
                if not pkt.ok:
                    garbled = True
                elif pkt.raw != frame and pkt.id == servo_id and shape(pkt):
                    answers.append(pkt)
                # other intact packets answer something else (a servo that heard another
                # one's status packet as a request): not an answer to this frame
        return answers, garbled or parser.skipped > 0 or parser.pending() > 0

    def duplicate(self, servo_id, tries=2, probes=("ping", "table")):
        """True if two (or more) servos answer at servo_id: two intact answers to one
        request (different return delays), or answers garbled by their collision — seen
        at each of `tries` requests in a row, so that a burst of noise is not taken for a
        collision. The probes: "ping" (PING) and "table" (a READ of the whole table).
        Two servos give the same PING answer, and on a real bus two identical answers
        sent at the same instant reach the host as one (the wire ANDs identical bits);
        their tables (model, settings, position, temperature) seldom match to the byte.
        Two servos identical to the byte cannot be told apart by any answer."""
        check_id(servo_id)
        V.strict_integer(tries, "tries", 1, 100)
        if not isinstance(probes, (list, tuple)) or not set(probes) <= {"ping", "table"}:
            raise RangeError("probes %r: give 'ping', 'table' or both" % (probes,))
        table = bytes([0, TABLE_SIZE])
        frames = {"ping": (P.instruction(servo_id, P.PING), answer_shape(P.PING), 7),
                  "table": (P.instruction(servo_id, P.READ, table),
                            lambda pkt: len(pkt.params) == TABLE_SIZE, 6 + TABLE_SIZE)}
        for probe in probes:
            frame, shape, nbytes = frames[probe]
            for i in range(tries):
                answers, garbled = self.listen(servo_id, frame, shape, nbytes)
                if len(answers) < 2 and not garbled:
                    break
            else:
                return True
        return False

    def in_update_mode(self, servo_id):
        """True if servo_id answers the §10 enter frame with `D5 5D ID 03 00 43` although
        (call it only then) it does not answer PING: its bootloader waits in update mode
        (a damaged application, or a new image that did not confirm itself after 3
        starts). A good image sent with update() brings it back."""
        check_id(servo_id)  # before the frame is built: 254, 255, -1, 'x' are refused
        answers, _ = self.listen(servo_id, P.update_enter(servo_id),
                                 lambda pkt: pkt.err == 0 and pkt.params == bytes([P.READY]))
        return bool(answers)

    def silent(self, servo_id, e):
        """The BusTimeout to raise for servo_id, which answered neither e's request nor
        a PING: e itself, or, if the servo waits in its bootloader's update mode (it
        answers the update handshake), one that says so (its update_mode is True)."""
        check_id(servo_id)
        if not isinstance(e, BusTimeout):
            raise RangeError("e: give the BusTimeout to explain, not %r" % (e,))
        if e.update_mode or not self.in_update_mode(servo_id):
            return e
        named = BusTimeout(
            "ID %d does not answer PING but answers the update handshake: %s — send a "
            "good image: `servoctl --id %d update FILE` (Bus.update)" % (
                servo_id, IN_UPDATE_MODE, servo_id), servo_id)
        named.update_mode = True
        return named

    def scan_window(self, baud=None):
        """Seconds a broadcast PING's answers take: the longest return delay plus one
        answer slot per ID 0-253 (§4.1), plus slack."""
        baud = self.baud if baud is None else baud
        if baud not in BAUD_RATES:
            raise RangeError("baud %r is not one of %s" % (baud, BAUD_RATES))
        return (P.MAX_RETURN_DELAY_S + (P.ID_MAX + 1) * P.SLOT_BYTES * P.byte_time(baud) +
                7 * P.byte_time(baud) + 0.06)

    def scan(self, all_bauds=False, check_duplicates=False):
        """Broadcast PING (ID-slotted answers, §4.1) at the bus baud, or at every baud of
        §5.2 with all_bauds. Returns a list of Found(id, baud, err) sorted by ID (and
        baud: two servos with one ID at two bauds are both listed). Over tcp:// the
        simulator hears every baud, so all_bauds scans once (harmless).
        Two servos on one ID: two answers in one slot, or a garbled slot, confirmed by
        duplicate(), or one ID answering at two bauds (resolve_bauds()); their IDs are
        in self.duplicates and scan_notes says so. Two servos whose PING answers
        coincide exactly reach the host as one answer: with check_duplicates, each ID
        found is also checked with a READ of its table (one answer window per servo:
        about 0.2 s at 9600 baud, 0.4 s over tcp://)."""
        self.scan_notes = []
        self.duplicates = []
        bauds = [self.baud]
        if all_bauds and self.is_tcp:
            self.scan_notes.append("over tcp:// every servo hears the host whatever its "
                                   "baud, so --all-bauds scans once")
        elif all_bauds:
            bauds = list(BAUD_RATES)
        finds = []
        start_baud = self.baud
        try:
            for baud in bauds:
                if baud != self.baud:
                    self.set_baud(baud)
                finds += self._scan_once({f.id for f in finds})
            found = self.resolve_bauds(finds)
            if check_duplicates:
                self._check_tables(found)
        finally:
            if self.baud != start_baud:
                self.set_baud(start_baud)
        return found

    def _check_tables(self, found):
        """Each ID found, not yet known to be two servos, checked with a READ of its
        table (two servos whose PING answers coincide differ there)."""
        for f in found:
            if f.id in self.duplicates:
                continue
            if f.baud != self.baud:
                self.set_baud(f.baud)
            if self.duplicate(f.id, probes=("table",)):
                self._note_duplicate(f.id, "their answers to a READ garble each other")

    def resolve_bauds(self, finds):
        """The servos behind the Found of scans at several bauds, sorted by ID and baud.
        An ID heard at two bauds is one servo heard at a neighbouring baud (896000 and
        921600 read each other, as real UARTs do) or two servos: the baud each one says
        it uses (register 4, read at the baud it was heard at) tells which. Two servos:
        both are listed, with their own baud, and the ID goes to self.duplicates."""
        if not isinstance(finds, (list, tuple)) or \
                not all(isinstance(f, Found) for f in finds):
            raise RangeError("finds: give the list of Found that scans returned")
        by_id = {}
        for f in finds:
            by_id.setdefault(f.id, []).append(f)
        out = []
        for servo_id, heard in sorted(by_id.items()):
            if len(heard) == 1:
                out.append(heard[0])
                continue
            own = {}
            for f in heard:
                baud = self._own_baud(f) or f.baud
                own.setdefault(baud, f._replace(baud=baud))
            out += [own[b] for b in sorted(own)]
            if len(own) > 1:
                self._note_duplicate(servo_id, "one answers at %s baud" % ", one at ".join(
                    str(b) for b in sorted(own)))
        return out

    def _own_baud(self, f):
        """The baud the servo found as f says it answers at (register 4 and its
        variant's default), read at the baud it was heard at; None if it does not say."""
        start = self.baud
        try:
            if f.baud != self.baud:
                self.set_baud(f.baud)
            v = self.read_many(f.id, ["model_number", "baud_rate"])
            return baud_of_code(v["baud_rate"], variant_by_model(v["model_number"]))
        except Interrupted:  # a STOP goes through every check
            raise
        except ServoBusError:
            return None
        finally:
            if self.baud != start:
                self.set_baud(start)

    def _scan_once(self, known):
        sent = self.send(P.BROADCAST, P.PING)
        t0 = time.monotonic()
        slot = P.SLOT_BYTES * P.byte_time(self.baud)
        parser = P.StatusParser()
        deadline = t0 + self.scan_window()
        out, seen, garbled_at = [], set(), []
        while time.monotonic() < deadline:
            try:
                data = self._read(deadline, parser)
            except Interrupted:
                # the servos after this point still answer in their slots: drained later
                self._quiet_at = max(self._quiet_at, deadline)
                raise
            skipped = parser.skipped
            for pkt in parser.feed(data):
                if pkt.raw == sent:
                    continue
                if not pkt.ok:
                    garbled_at.append(time.monotonic() - t0)
                    continue
                if len(pkt.params) != 1 or pkt.err != 0x01:
                    continue  # intact, but not a PING answer: it answers something else
                if pkt.id in seen:  # a second answer in one ID's slot
                    self._note_duplicate(pkt.id, "two answers at ID %d" % pkt.id)
                    continue
                seen.add(pkt.id)
                out.append(Found(pkt.id, self.baud, pkt.params[0]))
            if parser.skipped > skipped:
                garbled_at.append(time.monotonic() - t0)
        if parser.pending():
            garbled_at.append(self.scan_window())
        if garbled_at:
            self._explain_garbled(garbled_at, slot, seen | set(known))
        return out

    def _note_duplicate(self, servo_id, how):
        if servo_id not in self.duplicates:
            self.duplicates.append(servo_id)
            self.scan_notes.append(
                "two servos answer at ID %d (%s): see \"Two servos on one ID\" in "
                "tools/python/README.md" % (servo_id, how))

    def _explain_garbled(self, times, slot, answered):
        """Garbled bytes in a scan: find the ID whose slot they fell in (assuming the
        factory return delays, 4 or 8 ms) and check it with duplicate()."""
        candidates = []
        for t in times:
            for delay in (0.008, 0.004):
                n = int((t - delay) / slot)
                for i in (n, n - 1, n + 1):
                    if 0 <= i <= P.ID_MAX and i not in answered and i not in candidates:
                        candidates.append(i)
        for servo_id in candidates[:6]:
            if self.duplicate(servo_id):
                self._note_duplicate(servo_id, "their answers garble each other")
                return
        self.scan_notes.append(
            "garbled bytes in the answer window at %d baud, about %.0f ms after the "
            "PING: noise, or two servos with one ID (`servoctl --id N ping` checks ID N)"
            % (self.baud, times[0] * 1e3))
