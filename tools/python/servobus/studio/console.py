"""The wire console's record (issue 29): every frame the studio's Bus sends and
receives, timestamped and decoded (servobus/frames.py), each answer tied to the request
it belongs to, pushed to every tab in batches and kept for a tab opened later.

Recorder.tap is the Bus's tap (Link.tap): it runs in the worker thread, which owns the
Bus; the record is read in the event loop's thread, under a lock."""

import collections
import threading

from .. import frames as F
from .. import protocol as P

KEEP = 4000          # frames kept for a tab opened later (and for export)
FLUSH_S = 0.1        # frames go to the tabs in batches, at most ten a second


class Recorder:
    """The console's frames; tap(direction, data, t) is installed as the Bus's tap."""

    def __init__(self, st):
        self.st = st
        self.lock = threading.Lock()
        self.frames = collections.deque(maxlen=KEEP)
        self.pending = []
        self.flushing = False
        self.n = 0
        self.parser = P.StatusParser()
        self.request = None  # (entry, raw) of the last instruction sent

    def install(self, bus):
        bus.tap = self.tap

    def _resolution(self, sid):
        return self.st.resolutions.get(sid, 10)

    def tap(self, direction, data, t):
        """A packet sent ('tx') or bytes received ('rx') by the studio's Bus at t."""
        if direction == "tx":
            self._sent(bytes(data), t)
            return
        skipped = self.parser.skipped
        for pkt in self.parser.feed(data):
            self._received(pkt, t)
        if self.parser.skipped > skipped:
            self._add({"dir": "rx", "t": t, "hex": "", "id": None, "name": "garbage",
                       "summary": "%d bytes without a frame (noise, a baud mismatch or "
                       "two servos answering at once)" % (self.parser.skipped - skipped),
                       "err_words": [], "error": True, "answers": None, "cmd": None})

    def _sent(self, raw, t):
        try:
            d = F.decode_instruction(raw, self._resolution(raw[2]))
        except (IndexError, ValueError):  # a frame the decoder does not know: raw bytes
            d = {"id": raw[2] if len(raw) > 2 else None, "name": "frame", "summary": "",
                 "err_words": []}
        port = self.st.port if self.st.bus is None else self.st.bus.port
        baud = None if self.st.bus is None or self.st.bus.is_tcp else self.st.bus.baud
        entry = {"dir": "tx", "t": t, "hex": raw.hex(" "), "id": d["id"],
                 "name": d["name"], "summary": d["summary"], "err_words": [],
                 "error": False, "answers": None,
                 "cmd": F.servoctl(raw, port, baud, self._resolution(raw[2]))}
        self._add(entry)
        self.request = (entry, raw)
        self.parser = P.StatusParser()  # bytes of an earlier answer are not this one's

    def _received(self, pkt, t):
        req_entry, req = self.request if self.request else (None, None)
        if req is not None and pkt.raw == req:
            return  # an adapter's echo of the request
        belongs = req is not None and (req[2] == pkt.id or req[2] == P.BROADCAST)
        d = F.decode_status(pkt.raw, req if belongs else None, self._resolution(pkt.id))
        bad = d["err"] not in (0, None) or not pkt.ok
        self._add({"dir": "rx", "t": t, "hex": pkt.raw.hex(" "), "id": pkt.id,
                   "name": "status" if belongs else "status (no request for it)",
                   "summary": d["summary"], "err_words": d["err_words"], "error": bad,
                   "answers": req_entry["n"] if belongs else None,
                   "cmd": req_entry["cmd"] if belongs else None})

    def _add(self, entry):
        with self.lock:
            self.n += 1
            entry["n"] = self.n
            entry["t"] = round(entry["t"] - self.st.t0, 4)
            self.frames.append(entry)
            self.pending.append(entry)
            start = not self.flushing and self.st.loop is not None
            self.flushing = self.flushing or start
        if start:
            self.st.loop.call_soon_threadsafe(self.st.loop.call_later, FLUSH_S, self._flush)

    def _flush(self):
        with self.lock:
            batch, self.pending, self.flushing = self.pending, [], False
        if batch:
            self.st.push({"type": "frames", "frames": batch})

    def mark(self):
        with self.lock:
            return self.n

    def since(self, mark):
        """The frames recorded after mark (a number from mark())."""
        with self.lock:
            return [e for e in self.frames if e["n"] > mark]

    def between(self, first, last):
        """The frames recorded after mark first up to mark last (a job's frames)."""
        with self.lock:
            return [e for e in self.frames if first < e["n"] <= last]

    def recent(self, count=KEEP):
        with self.lock:
            return list(self.frames)[-count:]
