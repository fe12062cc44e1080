"""Discovery on the bus: the broadcast PING scan (§4.1), two servos on one ID, and a
servo waiting in its bootloader's update mode."""

import time

from . import protocol as P
from .link import Found, answer_shape, check_id
from .registers import BAUD_RATES


class Discovery:
    """Who is on the bus (a mixin of Bus: it uses Link's transport and transactions)."""

    def listen(self, servo_id, frame, shape):
        """Send a raw frame to servo_id and listen for the whole answer window (the
        longest return delay): (intact answers from servo_id shaped as `shape` wants,
        garbled: whether bytes arrived that are not such an answer)."""
        check_id(servo_id)
        self._drain()
        self._t.write(frame)
        parser = P.StatusParser()
        deadline = time.monotonic() + self.full_answer_time(16)
        answers, garbled = [], False
        while time.monotonic() < deadline:
            for pkt in parser.feed(self._t.read(deadline)):
                if pkt.raw == frame:
                    continue
                if pkt.ok and pkt.id == servo_id and shape(pkt):
                    answers.append(pkt)
                else:
                    garbled = True
        return answers, garbled or parser.skipped > 0 or parser.pending() > 0

    def duplicate(self, servo_id, tries=2):
        """True if two (or more) servos answer at servo_id: two intact answers to one
        request (different return delays), or answers garbled by their collision — seen
        at each of `tries` requests in a row, so that a burst of noise is not taken for a
        collision. Two requests are tried: PING, and a READ of the present registers
        (36-41: position, speed, turned angle). Two servos give the same PING answer, and
        on a real bus two identical answers sent at the same instant can reach the host
        as one; their positions differ, so their READ answers do not."""
        probes = [(P.instruction(servo_id, P.PING), answer_shape(P.PING))]
        read = bytes([36, 6])
        probes.append((P.instruction(servo_id, P.READ, read), answer_shape(P.READ, read)))
        for frame, shape in probes:
            for i in range(tries):
                answers, garbled = self.listen(servo_id, frame, shape)
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

    def scan(self, all_bauds=False):
        """Broadcast PING (ID-slotted answers, §4.1) at the bus baud, or at every baud of
        §5.2 with all_bauds. Returns a list of Found(id, baud, err) sorted by ID. Over
        tcp:// the simulator hears every baud, so all_bauds scans once (harmless).
        Two servos on one ID: two answers in one slot, or a garbled slot, confirmed by
        duplicate(); their IDs are in self.duplicates and scan_notes says so."""
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
                if not pkt.ok or len(pkt.params) != 1 or pkt.err != 0x01:
                    garbled_at.append(time.monotonic() - t0)
                    continue
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
