"""The servo's flash commit budget, estimated on the host (docs/persistence.md, "For
host tools"). The firmware keeps its EEPROM registers in flash at a limited rate: a
token bucket of STORE_BURST = 64 commits, one token back per 64 s (the refill clock
starts when the bucket last stood full), full at every power-up and restart. A write
past the budget is in force at once but reaches flash when the next token arrives, up
to 64 s later; a power cut before then keeps the old value.

Nothing on the bus tells the host whether a commit was deferred, so this is an
*estimate*: it counts the EEPROM writes this host made to each servo (one commit per
WRITE that may change an EEPROM value, RESET included), assumes the bucket was full
when it first saw the servo and that the servo has not power-cycled since (a power
cycle refills it: the estimate then errs on the side of warning), and knows nothing of
other hosts' writes. With a state file it survives from one servoctl run to the next."""

import json
import os
import time

BURST = 64          # STORE_BURST (include/store.h)
REFILL_S = 64.0     # STORE_REFILL_US
_FORGET_S = BURST * REFILL_S  # an entry this old is a full bucket again


class CommitBudget:
    """Per servo (a key: port and ID) token bucket replayed from this host's writes.
    path: a JSON file keeping the estimate between processes (None: in memory)."""

    def __init__(self, path=None, clock=time.time):
        self.path = path
        self.clock = clock
        self._state = {}  # key -> [tokens, token_at, pending]
        if path:
            try:
                with open(path, encoding="ascii") as f:
                    loaded = json.load(f)
                self._state = {k: [int(v[0]), float(v[1]), bool(v[2])]
                               for k, v in loaded.items()}
            except (OSError, ValueError, TypeError, IndexError, AttributeError):
                self._state = {}

    def _refill(self, key, now):
        """token_ready() of src/store.c, with a deferred commit spent as its token comes."""
        st = self._state.setdefault(key, [BURST, now, False])
        while st[0] < BURST and now - st[1] >= REFILL_S:
            st[0] += 1
            st[1] += REFILL_S
            if st[2]:  # the deferred commit runs as soon as a token arrives
                st[0] -= 1
                st[2] = False
        if st[0] == BURST:
            st[1] = now
        return st

    def tokens(self, key):
        """Commits the servo can make at once now (estimate)."""
        return self._refill(key, self.clock())[0]

    def commit(self, key):
        """Count one commit now. Returns 0.0 if it is (estimated) in flash at once, else
        the seconds until it reaches flash: do not cut the power before then."""
        now = self.clock()
        st = self._refill(key, now)
        if st[0] > 0:
            st[0] -= 1
            wait = 0.0
        else:
            st[2] = True
            wait = st[1] + REFILL_S - now
        self._save(now)
        return wait

    def restarted(self, key):
        """The servo restarted (an update, a power cycle the host caused): bucket full."""
        self._state.pop(key, None)
        self._save(self.clock())

    def moved(self, key, new_key):
        """The servo's ID changed: its bucket goes with it."""
        if key in self._state:
            self._state[new_key] = self._state.pop(key)
            self._save(self.clock())

    def copied(self, key, new_key):
        """A servo left an ID that others may still answer at (duplicates, issue 27):
        the new ID starts from the old one's estimate, which stays for the others."""
        if key in self._state:
            self._state[new_key] = list(self._state[key])
            self._save(self.clock())

    def _save(self, now):
        if not self.path:
            return
        keep = {k: v for k, v in self._state.items()
                if v[0] < BURST and now - v[1] < _FORGET_S}
        try:
            os.makedirs(os.path.dirname(os.path.abspath(self.path)), exist_ok=True)
            tmp = "%s.%d" % (self.path, os.getpid())
            with open(tmp, "w", encoding="ascii") as f:
                json.dump(keep, f)
            os.replace(tmp, self.path)
        except OSError:
            pass  # an estimate: never a reason to fail a command
