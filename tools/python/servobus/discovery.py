"""Discovery on the bus: the broadcast PING scan (§4.1), two servos on one ID, and a
servo waiting in its bootloader's update mode."""

import time

from . import protocol as P
from .link import Found, answer_shape, check_id
from .registers import BAUD_RATES, TABLE_SIZE


class Discovery:
    """Who is on the bus (a mixin of Bus: it uses Link's transport and transactions)."""

    def listen(self, servo_id, frame, shape, nbytes=16):
        """Send a raw frame to servo_id and listen for the whole answer window (the
        longest return delay and an answer of nbytes): (intact answers from servo_id
        shaped as `shape` wants, garbled: whether bytes arrived that are not such an
        answer). Intact packets of another shape are left out: they answer something
        else."""
        check_id(servo_id)
        # A second servo at the ID of the last request may still be answering it: wait
        # its window out (a request sent into an answer would collide on the wire).
        self._quiet_at = max(self._quiet_at,
                             self._sent_at + self.full_answer_time(6 + TABLE_SIZE))
        self._drain()
        self._t.write(frame)
        self._sent_at = time.monotonic()
        parser = P.StatusParser()
        deadline = time.monotonic() + self.full_answer_time(nbytes)
        answers, garbled = [], False
        while time.monotonic() < deadline:
            for pkt in parser.feed(self._t.read(deadline)):
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
        answers, _ = self.listen(servo_id, P.update_enter(servo_id),
                                 lambda pkt: pkt.err == 0 and pkt.params == bytes([P.READY]))
        return bool(answers)

    def scan_window(self, baud=None):
        """Seconds a broadcast PING's answers take: the longest return delay plus one
        answer slot per ID 0-253 (§4.1), plus slack."""
        baud = baud or self.baud
        return (P.MAX_RETURN_DELAY_S + (P.ID_MAX + 1) * P.SLOT_BYTES * P.byte_time(baud) +
                7 * P.byte_time(baud) + 0.06)

    def scan(self, all_bauds=False, check_duplicates=False):
        """Broadcast PING (ID-slotted answers, §4.1) at the bus baud, or at every baud of
        §5.2 with all_bauds. Returns a list of Found(id, baud, err) sorted by ID. Over
        tcp:// the simulator hears every baud, so all_bauds scans once (harmless).
        Two servos on one ID: two answers in one slot, or a garbled slot, confirmed by
        duplicate(); their IDs are in self.duplicates and scan_notes says so. Two
        servos whose PING answers coincide exactly reach the host as one answer: with
        check_duplicates, each ID found is also checked with a READ of its table (one
        answer window per servo: about 0.2 s at 9600 baud, 0.4 s over tcp://)."""
        self.scan_notes = []
        self.duplicates = []
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
                for f in self._scan_once(found):
                    found.setdefault(f.id, f)
            if check_duplicates:
                for f in sorted(found.values()):
                    if f.id in self.duplicates:
                        continue
                    if f.baud != self.baud:
                        self.set_baud(f.baud)
                    if self.duplicate(f.id, probes=("table",)):
                        self._note_duplicate(f.id, "their answers to a READ garble "
                                             "each other")
        finally:
            if self.baud != start_baud:
                self.set_baud(start_baud)
        return [found[i] for i in sorted(found)]

    def _scan_once(self, known):
        sent = self.send(P.BROADCAST, P.PING)
        t0 = time.monotonic()
        slot = P.SLOT_BYTES * P.byte_time(self.baud)
        parser = P.StatusParser()
        deadline = t0 + self.scan_window()
        out, seen, garbled_at = [], set(), []
        while time.monotonic() < deadline:
            data = self._t.read(deadline)
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
