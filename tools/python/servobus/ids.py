"""Every servo by its unique identity (issue 27): enumerate a bus whatever the IDs,
duplicates and factory-fresh servos included, identify one, and give one servo an ID by
its UID while others share its old one. The wire format (CUSTOM sub-command 0x11) is in
docs/decisions.md, "Identity"; the firmware side in include/ident.h.

The search: ENUMERATE(k, prefix) makes every servo whose UID starts with the k-nibble
prefix (nibble i: byte i // 2, low nibble first) answer in slot s = its nibble k, one of
16. A slot with one answer gives that servo (the UID's complement checks it). Two or
more answers in one slot either superimpose bit for bit (the line is the AND of the
talkers at low bauds, where their few microseconds of offset are a fraction of a bit):
then the answer shows the first bit where their UIDs differ, and the next round asks
from that bit's nibble on, so each such round splits a group of servos in two or more -
at most N - 1 of them for N servos, N rounds in all; or they garble into bytes nobody
can place (high bauds): then every slot that gave no clean answer is asked again, one
nibble deeper, so at most 1 + 16 * 23 * (N - 1) rounds, in practice a few per servo
that collided. Measured figures: make bench."""

import collections
import time

from . import protocol as P
from . import values as V
from .errors import BusTimeout, DuplicateId, DuplicateUid, IdTaken, Interrupted, \
    ProtocolError, RangeError, ServoBusError
from .link import check_id
from .registers import BAUD_RATES, VARIANTS, baud_of_code, variant_by_model

SUB = P.CUSTOM_SUBS["identity"]["sub"]
# SET ID writes register 3: one flash commit, which the budget model counts (budget.py)
SET_ID_COMMITS = "commits" in P.CUSTOM_SUBS["identity"]["flags"]
ENUMERATE = 0x01
IDENTIFY = 0x02
SET_ID = 0x03
UID_BYTES = 12
UID_BITS = 96
ANSWER_ID = 0xFF
ANSWER_DATA = 6 + 2 * UID_BYTES
ANSWER_BYTES = 6 + ANSWER_DATA  # 36
TURNAROUND_S = 500e-6
GUARD_S = 100e-6
SLOTS = 16
NIBBLES = 2 * UID_BYTES
VARIANT_NAMES = tuple(VARIANTS)  # the firmware's variant index: registers.json's order
HEADER = bytes([P.HEADER[0], P.HEADER[1], ANSWER_ID, ANSWER_DATA + 2])

Identity = collections.namedtuple("Identity", "uid id variant model baud err")
Identity.__doc__ = """One servo: uid (12 bytes), id, variant (name), model number,
baud (bit/s, from register 4), err (its ERR byte)."""


def uid_text(uid):
    """A UID as the CLI prints it: 24 hex digits, byte 0 first."""
    return bytes(uid).hex()


def parse_uid(text):
    """24 hex digits (spaces and colons allowed) -> 12 bytes; RangeError otherwise."""
    if isinstance(text, (bytes, bytearray)):
        uid = bytes(text)
    else:
        try:
            uid = bytes.fromhex(str(text).replace(":", "").replace(" ", ""))
        except ValueError:
            uid = b""
    if len(uid) != UID_BYTES:
        raise RangeError("UID %r: give 24 hex digits (12 bytes)" % (text,))
    return uid


def slot_time(baud):
    """Seconds of one ENUMERATE answer slot: the answer, 4 byte-times and the guard
    (as the firmware's ident_slot_us)."""
    return (ANSWER_BYTES + 4) * P.byte_time(baud) + GUARD_S


def _bit(value, i):
    return (value >> i) & 1


def _uid_int(uid):
    return int.from_bytes(uid, "little")  # bit i: byte i // 8, bit i % 8


def _decode(raw):
    """An answer's 36 bytes -> ("one", Identity) for a single talker, ("and", U, C) for
    answers superimposed bit for bit (U the AND of the UIDs, C of their complements),
    ("clone", uid) for answers superimposed whose UIDs are one (each UID bit and its
    complement intact, the checksum not: two servos report that UID), or None."""
    if len(raw) != ANSWER_BYTES or raw[:4] != HEADER:
        return None
    uid, comp = raw[6:18], raw[23:35]
    u, c = _uid_int(uid), _uid_int(comp)
    full = (1 << UID_BITS) - 1
    ok = sum(raw[2:-1]) & 0xFF == raw[-1]
    if ok and u ^ c == full:
        model = raw[20] | raw[21] << 8
        name = VARIANT_NAMES[raw[19]] if raw[19] < len(VARIANT_NAMES) else "?"
        baud = baud_of_code(raw[22], variant_by_model(model)) \
            if raw[22] <= len(BAUD_RATES) else None
        return ("one", Identity(bytes(uid), raw[18], name, model, baud, raw[4]))
    if u ^ c == full and raw[5] in (ENUMERATE, IDENTIFY):
        return ("clone", bytes(uid))
    if u & c == 0 and u | c != full:
        return ("and", u, c, raw[5])
    return None


def _identities(idents):
    """A list of Identity, or RangeError."""
    if not isinstance(idents, (list, tuple)) or \
            not all(isinstance(i, Identity) for i in idents):
        raise RangeError("idents: give the list enumerate() returned, not %r" % (idents,))
    return list(idents)


def _id_list(ids, what):
    """A list of servo IDs 0-253, or RangeError."""
    if isinstance(ids, (str, bytes, dict)) or not isinstance(ids, (list, tuple, set, range)):
        raise RangeError("%s: give a list of IDs 0-253, not %r" % (what, ids))
    out = []
    for i in ids:
        if isinstance(i, bool) or not isinstance(i, int) or not 0 <= i <= P.ID_MAX:
            raise RangeError("%s: %r is not an ID 0-253" % (what, i))
        out.append(i)
    return out


class Ids:
    """Enumerate, identify, set an ID by UID (a mixin of Bus: it uses Link)."""

    def _ident(self, to, op, params, window, baud=None):
        """Send CUSTOM 0x11 op to `to` and collect every 36-byte answer window (seconds
        after the request has left) holds: (decoded answers, garbage seen)."""
        frame = P.instruction(to, P.CUSTOM, bytes([SUB, op]) + bytes(params))
        self._drain()
        self.check_stop()
        self._put(frame)
        sent = time.monotonic()
        # Bus(timeout=) widens the slack (a simulator behind real time, a slow adapter)
        slack = self.slack() if self.timeout is None else max(self.slack(), self.timeout)
        deadline = sent + len(frame) * P.byte_time(self.baud) + window + slack
        self._quiet_at = max(self._quiet_at, deadline)
        buf = bytearray()
        while time.monotonic() < deadline:
            buf += self._read(deadline)
        if buf.startswith(frame):  # an adapter's echo of the request
            del buf[:len(frame)]
        found, garbage = [], False
        while buf:
            i = buf.find(HEADER)
            if i < 0:
                garbage = garbage or any(buf)
                break
            if i:
                garbage = True
            del buf[:i]
            got = _decode(bytes(buf[:ANSWER_BYTES]))
            if got is None:
                garbage = True
                del buf[:2]
                continue
            found.append(got)
            del buf[:ANSWER_BYTES]
        return found, garbage

    def enumerate_round(self, k, prefix):
        """One ENUMERATE: servos whose UID starts with the k-nibble prefix (an int, bit i
        of the UID its bit i) answer in 16 slots. Returns (identities, splits, garbled):
        splits a list of (k', prefix') to ask next, read from superimposed answers;
        garbled True if bytes came that no slot can be told from. self.round_clones: the
        UIDs (as text) whose answer kept the UID and its complement but not the checksum:
        two servos with that UID, or one answer hit by noise outside its UID."""
        V.strict_integer(k, "prefix nibbles", 0, NIBBLES - 1)
        if isinstance(prefix, bool) or not isinstance(prefix, int) or prefix < 0:
            raise RangeError("prefix %r: give the UID's first bits as an int >= 0" % (prefix,))
        bits = 4 * k
        pbytes = (prefix & ((1 << bits) - 1)).to_bytes(UID_BYTES, "little")[:(k + 1) // 2]
        window = TURNAROUND_S + SLOTS * slot_time(self.baud)
        found, garbage = self._ident(P.BROADCAST, ENUMERATE, bytes([k]) + pbytes, window)
        ids, splits = [], []
        self.round_clones = set()
        mask = (1 << bits) - 1
        for got in found:
            if got[0] == "one":
                ids.append(got[1])
                continue
            if got[0] == "clone":
                self.round_clones.add(uid_text(got[1]))
                continue
            _, u, c, _op = got
            if u & mask != prefix & mask or (~c) & mask != prefix & mask:
                garbage = True  # not under this prefix: not a superposition of answers
                continue
            split = next(i for i in range(UID_BITS) if not _bit(u, i) and not _bit(c, i))
            nib = split // 4
            if nib <= k or got[3] != ENUMERATE:
                # answers in one slot agree on its nibble: a first difference there, or
                # below, is garbage that happens to look like a superposition
                garbage = True
                continue
            splits.append((nib, u & ((1 << (4 * nib)) - 1)))
        return ids, splits, garbage

    def enumerate(self, max_rounds=5000):
        """Every servo on the bus at this baud, whatever its ID: a list of Identity sorted
        by (id, uid). self.enumerate_rounds says how many ENUMERATE rounds it took.
        DuplicateUid (its .found the servos told apart) when two servos report one UID
        (a cloned part)."""
        V.strict_integer(max_rounds, "max_rounds", 1, 100000)
        self.enumerate_clones = set()
        again = set()  # rounds asked twice: a clone's signs, or noise once?
        found = {}
        # (k, prefix, fallback): fallback is asked when a split read from a superposed
        # answer finds nobody clean (garbage that looked like a superposition)
        todo = collections.deque([(0, 0, None)])
        asked = set()
        rounds = 0
        while todo:
            k, prefix, fallback = todo.popleft()
            if (k, prefix) in asked:
                continue
            asked.add((k, prefix))
            if rounds >= max_rounds:
                raise ServoBusError("enumerate: still collisions after %d rounds" % rounds)
            ids, splits, garbled = self.enumerate_round(k, prefix)
            rounds += 1
            clean = set()
            for ident in ids:
                found[ident.uid] = ident
                clean.add((_uid_int(ident.uid) >> (4 * k)) & 15)
            for nib, pre in splits:
                slot = (pre >> (4 * k)) & 15
                deeper = (k + 1, prefix | slot << (4 * k), None) if k + 1 < NIBBLES else None
                todo.append((nib, pre, deeper))
            if fallback is not None and not ids and not splits:
                todo.append(fallback)
            if garbled and k + 1 < NIBBLES:
                for s in range(SLOTS):
                    if s not in clean:
                        todo.append((k + 1, prefix | s << (4 * k), None))
            # Two servos with one UID: their answers keep the UID and its complement but
            # not the checksum, or, garbled, still garble at the last nibble. Noise does
            # that once; a clone every time the round is asked.
            deepest = garbled and k + 1 == NIBBLES
            if (self.round_clones or deepest) and (k, prefix) not in again:
                again.add((k, prefix))
                asked.discard((k, prefix))
                todo.append((k, prefix, None))
                continue
            self.enumerate_clones |= self.round_clones
            if deepest:  # nibble k (text digit 22: byte 11's high nibble) unknown
                text = uid_text(prefix.to_bytes(UID_BYTES, "little"))
                self.enumerate_clones.add(text[:22] + "?" + text[23:])
        self.enumerate_rounds = rounds
        found = sorted(found.values(), key=lambda i: (i.id, i.uid))
        clones = sorted(self.enumerate_clones - {uid_text(i.uid) for i in found})
        if clones:
            raise DuplicateUid(
                "more than one servo reports UID %s (a cloned or copied part): they cannot "
                "be told apart by UID; %d other servo(s) found" % (
                    ", ".join(clones), len(found)), found, clones)
        return found

    def identify(self, uid=None, servo_id=None):
        """The Identity of the servo with uid (at any ID), or of the one at servo_id.
        BusTimeout if none answers."""
        if uid is not None:
            uid = parse_uid(uid)
            to = P.BROADCAST if servo_id is None else check_id(servo_id) or servo_id
            found, garbage = self._ident(to, IDENTIFY, uid, TURNAROUND_S + slot_time(self.baud))
        else:
            check_id(servo_id)
            found, garbage = self._ident(servo_id, IDENTIFY, b"",
                                         TURNAROUND_S + slot_time(self.baud))
        ones = [g[1] for g in found if g[0] == "one"]
        if uid is not None:
            ones = [i for i in ones if i.uid == uid]
        if len(ones) == 1 and not garbage:
            return ones[0]
        if ones or garbage or found:
            if uid is not None:
                raise ProtocolError("UID %s: its IDENTIFY answer came garbled %s" % (
                    uid_text(uid), self._where()))
            raise DuplicateId("more than one servo answers at ID %s: identify them by UID "
                              "(`servoctl ids`)" % servo_id)
        who = "UID %s" % uid_text(uid) if uid is not None else "ID %d" % servo_id
        raise BusTimeout("%s does not answer IDENTIFY %s" % (who, self._where()), servo_id)

    def set_id_by_uid(self, uid, new_id, check_free=True, verify=True, old_id=None):
        """Give the servo with uid (at any ID, others may share it) the ID new_id, kept in
        flash as any ID write; then confirm it by IDENTIFY. IdTaken if another servo
        already answers at new_id (check_free). verify=False: one broadcast frame, no
        check (fix_duplicates checks them all with one enumerate()); old_id its ID then,
        for the commit budget (the servo's estimate goes with it to the new ID)."""
        uid = parse_uid(uid)
        if isinstance(new_id, bool) or not isinstance(new_id, int) or \
                not 0 <= new_id <= P.ID_MAX:
            raise RangeError("ID %r is out of range 0..253" % (new_id,))
        if not verify:
            frame = self.send(P.BROADCAST, P.CUSTOM, bytes([SUB, SET_ID]) + uid +
                              bytes([new_id]))
            # frames sent back to back queue up on the wire: the next request's answer
            # window starts only once they have all left it (the servo answers none)
            self._quiet_at = max(self._quiet_at, time.monotonic()) + \
                len(frame) * P.byte_time(self.baud)
            self._variants.pop(new_id, None)
            self._count_commit(new_id, old_id)
            return None
        before = self.identify(uid)
        if before.id == new_id:
            return before
        if check_free:
            self.refuse_taken(new_id)
        self._ident(P.BROADCAST, SET_ID, uid + bytes([new_id]), 0.0)
        self._variants.pop(before.id, None)
        self._variants.pop(new_id, None)
        for _ in range(8):  # an ID write waits for the flash commit: give it time
            self.pause(0.05)
            try:
                after = self.identify(uid)
            except BusTimeout:
                continue
            if after.id == new_id:
                self._count_commit(new_id, before.id)
                return after
        raise ProtocolError("UID %s did not take ID %d" % (uid_text(uid), new_id))

    def _count_commit(self, new_id, old_id):
        if SET_ID_COMMITS:
            if old_id is not None and old_id != new_id:  # its bucket, not a fresh one
                self.commit_budget.copied(self.budget_key(old_id), self.budget_key(new_id))
            self.commit_wait = self.commit_budget.commit(self.budget_key(new_id))

    def fix_duplicates(self, idents=None, free=None):
        """Give every servo that shares an ID with another a free ID. The one with the
        lowest UID (as printed: 24 hex digits, byte 0 first, compared as text) keeps the
        old ID; the
        others take the lowest free IDs in turn (from 1 up; `free` may give the list),
        never one a servo holds at another baud the port can reach, nor one that answers
        a broadcast PING (a servo in a §10 update session keeps out of ENUMERATE).
        IdTaken, with nothing written, when there are fewer free IDs than servos to move.
        Returns [(uid, old id, new id)]."""
        idents = self.enumerate() if idents is None else _identities(idents)
        if free is not None:
            free = _id_list(free, "free")
        by_id = collections.defaultdict(list)
        for i in idents:
            by_id[i.id].append(i)
        taken = set(by_id)
        if any(len(g) > 1 for g in by_id.values()):  # only when an ID is to be given
            taken |= self._ids_at_other_bauds()
            # a servo in a §10 update session answers PING, never ENUMERATE
            taken |= {f.id for f in self.scan()}
        # each free ID once (a list naming one twice would put two servos on it)
        pool = [n for n in dict.fromkeys(free if free is not None else
                                         range(1, P.ID_MAX + 1)) if n not in taken]
        moves = []
        for sid in sorted(by_id):
            group = sorted(by_id[sid], key=lambda i: i.uid)
            for ident in group[1:]:
                moves.append((ident.uid, sid, pool.pop(0) if pool else None))
        short = [m for m in moves if m[2] is None]
        if short:  # refused before anything is written: never a half-separated bus
            raise IdTaken("not enough free IDs: %d servo(s) share an ID, %d free ID(s); "
                          "nothing was written" % (len(moves), len(moves) - len(short)))
        for uid, old, new in moves:
            self.set_id_by_uid(uid, new, check_free=False, verify=False, old_id=old)
        left = list(moves)
        for attempt in range(4):  # one check of them all; what did not take is sent again
            if not left:
                break
            self.pause(0.05)
            now = {i.uid: i.id for i in self.enumerate()}
            left = [m for m in left if now.get(m[0]) != m[2]]
            for uid, old, new in left if attempt < 3 else ():
                self.set_id_by_uid(uid, new, check_free=False, verify=False, old_id=old)
        if left:
            raise ProtocolError("%d servo(s) did not take their new ID: %s" % (
                len(left), ", ".join("UID %s -> %d" % (uid_text(u), n) for u, _, n in left)))
        return moves

    def _ids_at_other_bauds(self):
        """The IDs of servos at the other bauds this port can reach (one enumerate() at
        each; none over tcp://, which hears every baud): a servo there shares an ID as
        soon as either changes its baud, so set_id refuses such an ID, and so does this."""
        start, ids = self.baud, set()
        try:
            for baud in self.reachable_bauds():
                if baud == start:
                    continue
                try:
                    self.set_baud(baud)
                except Interrupted:
                    raise
                except ServoBusError:
                    continue  # the adapter cannot do it: no servo is reachable there
                try:
                    ids |= {i.id for i in self.enumerate()}
                except DuplicateUid as e:
                    ids |= {i.id for i in e.found}
        finally:
            if self.baud != start:
                self.set_baud(start)
        return ids

    def adopt(self, expect, idents=None, known=None):
        """A replacement servo: of the expected IDs exactly one is silent, and exactly one
        servo is new: it answers at an ID outside them, or shares an expected ID (a
        factory-fresh servo at ID 1 beside the old ID 1) while `known` (a dict UID ->
        ID, from an earlier `servoctl ids`) names the other one as the old servo there.
        Give it the missing ID, then this bus's baud (register 4) if it talks at another;
        when no newcomer answers at this baud, it is looked for at the others (the
        factory's first; over tcp:// too: a slower servo's answers outlast this baud's
        window).
        Refuses (ServoBusError, nothing written) when that is ambiguous: no or several
        silent IDs, no or several newcomers, or two servos on an expected ID that
        `known` cannot tell apart. Returns (uid, new id)."""
        if known is not None and (not isinstance(known, dict) or not all(
                isinstance(u, bytes) and len(u) == UID_BYTES and isinstance(i, int)
                for u, i in known.items())):
            raise RangeError("known: give a dict of 12-byte UIDs to IDs, not %r" % (known,))
        known = dict(known or {})
        expect = sorted(set(_id_list(expect, "expected IDs")))
        if not expect:
            raise RangeError("adopt: give the expected IDs")
        idents_given = idents
        idents = self.enumerate() if idents is None else _identities(idents)
        present = collections.Counter(i.id for i in idents)
        newcomers = [i for i in idents if i.id not in expect]
        shared = []
        for e in sorted(x for x in expect if present[x] > 1):
            unknown = [i for i in idents if i.id == e and known.get(i.uid) != e]
            if len(unknown) == present[e] - 1:
                newcomers += unknown
            else:
                shared.append(e)
        if shared:
            raise ServoBusError(
                "adopt is ambiguous: two servos answer at expected ID %s, and nothing tells "
                "the old one from the new: separate them first (`servoctl ids --fix`) or "
                "give the new one its ID by UID" % ", ".join(map(str, shared)))
        missing = [e for e in expect if present[e] == 0]
        if len(missing) != 1:
            raise ServoBusError("adopt needs exactly one silent expected ID; %s" % (
                "none is silent" if not missing else
                "silent: %s" % ", ".join(map(str, missing))))
        new = newcomers
        bus_baud = self.baud
        if not new and idents_given is None:
            new = self._newcomer_at_other_bauds()  # a factory-fresh one: 9600 or 115200
        if len(new) != 1:
            raise ServoBusError("adopt needs exactly one servo outside the expected IDs; "
                                "%s" % ("there is none" if not new else "there are %d (%s)" % (
                                    len(new), ", ".join("ID %d UID %s" % (i.id, uid_text(i.uid))
                                                        for i in new))))
        try:  # at the newcomer's baud (where it was found)
            got = self.set_id_by_uid(new[0].uid, missing[0], check_free=False)
            if got.baud != bus_baud:
                # Its answer would come at its old baud, which a serial host does not
                # hear: sent without waiting, then proved by IDENTIFY at the new one.
                self.send(missing[0], P.WRITE, bytes([4, BAUD_RATES.index(bus_baud) + 1]))
                self._late_until(b"", 8)
                self.pause(0.05)
        finally:
            if self.baud != bus_baud:
                self.set_baud(bus_baud)
        if got.baud != bus_baud and self.identify(new[0].uid).baud != bus_baud:
            raise ProtocolError("ID %d did not take %d baud" % (missing[0], bus_baud))
        return new[0].uid, missing[0]

    def _newcomer_at_other_bauds(self):
        """No newcomer at this baud: the servos whose register 4 says another baud, found
        at the first other baud that has any (the factory's first), this Bus left at
        that baud; [] (and the Bus at its own baud) if none."""
        start = self.baud
        factory = [9600, 115200]  # register 4 code 0: base 115200, the others 9600
        for baud in factory + [b for b in BAUD_RATES if b not in factory]:
            if baud == start:
                continue
            try:
                self.set_baud(baud)
                found = [i for i in self.enumerate() if i.baud != start]
            except Interrupted:
                self.set_baud(start)
                raise
            except ServoBusError:
                continue  # the adapter cannot do it, or clones there: not this one
            if found:
                return found
        self.set_baud(start)
        return []
