"""Who a servo is: giving it a new ID, the check that an ID is free at every baud the
port reaches, and a factory reset that succeeds only on proof from the servo."""

import time

from . import protocol as P
from .errors import BusTimeout, DuplicateId, IdTaken, Interrupted, ProtocolError, \
    RangeError, ServoBusError
from .link import check_id
from .registers import BAUD_RATES

# Seconds a RESET that was not answered is given to show up at ID 1.
RESET_SETTLE_S = 1.0


class Identity:
    """IDs and factory reset (a mixin of Bus: it uses Link, Discovery and Control)."""

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

    def reachable_bauds(self):
        """The bauds a servo on this port can answer at: this Bus's baud over tcp://
        (servo-sim hears every baud there), every baud of §5.2 on a serial port or
        rfc2217://, this Bus's first."""
        if self.is_tcp:
            return [self.baud]
        return [self.baud] + [b for b in BAUD_RATES if b != self.baud]

    def refuse_taken(self, new_id):
        """IdTaken if a servo answers a PING at new_id at any baud the port can reach (a
        servo at another baud would share the ID as soon as either changed its baud):
        two PINGs with the full time-out at each baud, so that one lost or late answer
        does not make a taken ID look free. On a serial port that is about 0.3 s per
        baud; a baud the adapter cannot set is skipped."""
        check_id(new_id)
        start = self.baud
        try:
            for baud in self.reachable_bauds():
                try:
                    if baud != self.baud:
                        self.set_baud(baud)
                except Interrupted:  # a STOP goes through every check
                    raise
                except ServoBusError:
                    continue  # the adapter cannot do it: no servo is reachable there
                if any(self.present(new_id, timeout=self.full_answer_time())
                       for _ in range(2)):
                    raise IdTaken(
                        "ID %d is already taken on the bus (a servo answered a PING there"
                        "%s); choose another ID or move that servo first" % (
                            new_id, "" if baud == start else " at %d baud" % baud))
        finally:
            if self.baud != start:
                self.set_baud(start)

    def reset(self, servo_id, check_free=True):
        """RESET to factory values (ID 1, default baud...); answered with the old ID.
        Refuses (IdTaken) if another servo answers at ID 1, where this one would land.
        Succeeds only on proof from the addressed servo: its answer to the RESET, or,
        for one that does not answer writes (status return level 0 or 1), that it has
        left servo_id and a servo at factory settings answers at ID 1. Nothing answers
        at servo_id: BusTimeout at once (saying so if it waits in update mode)."""
        check_id(servo_id)
        if check_free and servo_id != 1:
            self.refuse_taken(1)
        try:
            self.ping(servo_id)  # the servo to reset must be there (update mode is named)
        except BusTimeout as e:
            raise BusTimeout("nothing was reset: %s" % e, servo_id) from None
        try:
            pkt = self.transact(servo_id, P.RESET, what="RESET")
        except BusTimeout:
            pkt = None
        if pkt is None and not self._reset_took(servo_id):
            raise BusTimeout(
                "ID %d did not answer the RESET, and nothing shows it reset: it still "
                "answers at ID %d, or no servo at factory settings answers at ID 1" % (
                    servo_id, servo_id), servo_id)
        self.confirmed = True
        self.commit_wait = self.commit_budget.commit(self.budget_key(servo_id))
        if servo_id != 1:
            self.commit_budget.moved(self.budget_key(servo_id), self.budget_key(1))
        self._variants.clear()
        self._levels.pop(servo_id, None)
        self._levels.pop(1, None)

    def _reset_took(self, servo_id):
        """After a RESET that was not answered (the servo answered PING before it): is
        there proof from that servo? At another ID: it no longer answers there, and a
        servo answers at ID 1 at level 2 (factory; garbled if one was there already).
        At ID 1: it answers READ there at level 2, which it did not before (it kept
        silent: level 0 or 1)."""
        deadline = time.monotonic() + RESET_SETTLE_S
        while True:
            saved, self.timeout = self.timeout, None
            try:
                gone = servo_id == 1 or not self.present(servo_id)
                if gone and self.read_raw(1, 16, 1)[0] == 2:
                    return True
            except ProtocolError:  # garbled at ID 1: it landed beside a servo there
                if servo_id != 1 and not self.present(servo_id):
                    return True
            except Interrupted:  # a STOP goes through every check
                raise
            except ServoBusError:
                pass
            finally:
                self.timeout = saved
            if time.monotonic() > deadline:
                return False
            self.pause(0.05)
