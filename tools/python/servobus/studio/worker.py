"""The studio's shared state and the worker thread that owns the Bus.

One worker thread owns the Bus: actions are jobs in its queue (jobs.py), and between
jobs it samples the selected servo at SAMPLE_HZ and reads its whole table every
TABLE_PERIOD_S. Only the Bus's public API and the registers module are used.

STOP is never late: request_stop() sets the Bus's stop_event, which cuts the job under
way short at its next packet boundary (a scan, a dump, an update, a retry: the SDK looks
at it between packets and while it waits for an answer), cancels every queued motion,
and puts the broadcast first in the queue. While the bus is gone, every action is
refused at once; nothing is kept for later. The log says what was sent when it was
sent: an entry is made by the worker, at the time the job ran."""

import asyncio
import json
import threading
import time

from .. import Bus, Interrupted, ServoBusError
from ..registers import baud_of_code, variant_by_model
from . import sampler
from .console import Recorder
from .live import Live
from .jobs import BusGone, Job, JobQueue, Refused
from .words import in_words, is_link_error

SAMPLE_HZ = 30            # live samples per second at most (the plot needs >= 20)
TABLE_PERIOD_S = 1.0      # whole control table of the selected servo
LOG_KEEP = 200
RECONNECT_S = 0.5


class Studio:
    """The shared state and the worker thread that owns the Bus."""

    def __init__(self, bus, url):
        self.bus = bus
        self.port = bus.port
        self.url = url
        self.stop_event = threading.Event()
        self.resolutions = {}
        self.recorder = Recorder(self)
        self._own(bus)
        self.t0 = time.monotonic()  # the log's times count from here
        self.loop = None            # the event loop, and the thread it runs in
        self.loop_thread = None
        self.clients = set()
        self.queue = JobQueue()
        self.running = None         # the job the worker runs now
        self.stopping = False
        self.selected = None
        self.variant = None
        self.resolution = 10
        self.busy = None            # what holds the bus for a while (scan, update)
        self.sample_error = None
        self.rate = 0.0             # live samples in the last second
        self._stamps = []
        self.table_due = 0.0
        self.commands = 0           # actions of the user that put something on the wire
        self.nsample = 0
        self.slow = {}              # homing and photo switches from the last full sample
        self.gone_cause = ""        # why the bus is gone, in the bus's words (once)
        self.held = set()           # IDs that may hold a REG WRITE the studio sent
        self.live = Live(self)      # the dashboard and the plot of any register (live.py)
        self.state = {
            "port": bus.port, "baud": bus.baud, "tcp": bus.is_tcp, "link": "connected",
            "link_ok": True, "servos": [], "selected": None, "busy": None,
            "scan": {"running": False, "done": 0, "total": 0, "baud": None,
                     "notes": [], "warning": "", "message": ""},
            "ids": {"rows": [], "shared": [], "message": ""},  # idpanel.py (issue 27)
            "update": {"running": False, "id": None, "done": 0, "total": 0, "bytes": 0,
                       "bytes_total": 0, "before": None, "after": None, "error": "",
                       "note": "", "file": "", "step": None},
            "log": [], "commands": 0, "sample_error": "", "rate": 0.0,
            # the log's times count from here (time.monotonic(), CLOCK_MONOTONIC)
            "started": self.t0,
        }
        self.thread = threading.Thread(target=self._work, name="studio-bus", daemon=True)

    def _own(self, bus):
        bus.raise_faults = False  # fault bits are shown, not raised
        bus.stop_event = self.stop_event
        self.recorder.install(bus)

    # ---- state and clients ----------------------------------------------------------

    def push(self, msg):
        """Send msg to every tab (from any thread). It is encoded in the event loop's
        thread, so the state is read in one place."""
        if self.loop is None:
            return

        def send():
            text = json.dumps(msg)
            for ws in list(self.clients):
                if not ws.closed:
                    asyncio.ensure_future(ws.send_str(text))
        self.loop.call_soon_threadsafe(send)

    def changed(self):
        self.state["selected"] = self.selected
        self.state["busy"] = self.busy
        self.state["commands"] = self.commands
        self.push({"type": "state", "state": self.state})

    def log(self, text, ok=True, at=None):
        """A log entry; at: when it happened (time.monotonic(), default now). From the
        worker thread the entry is added in the event loop's thread, where the state is
        encoded: never while a tab's copy is being written."""
        t = (time.monotonic() if at is None else at) - self.t0
        entry = {"t": round(t, 1), "text": text, "ok": ok}
        if self.loop is not None and threading.get_ident() != self.loop_thread:
            self.loop.call_soon_threadsafe(self._add_log, entry)
        else:
            self._add_log(entry)

    def _add_log(self, entry):
        self.state["log"].append(entry)
        del self.state["log"][:-LOG_KEEP]
        self.changed()

    # ---- jobs -----------------------------------------------------------------------

    def require_bus(self):
        """BusGone if the bus is not there: an action is refused at once, never kept
        to run when it comes back."""
        if self.bus is None:
            raise BusGone("The bus is gone (%s): nothing was sent. Try again once the "
                          "header says connected." % self.gone_cause)

    def submit(self, fn, what=None, motion=False, prio=1):
        """Queue fn(bus) for the worker; its Future (BusGone at once without a bus)."""
        self.require_bus()
        return self.queue.put(Job(fn, what, motion, prio))

    async def call(self, fn, what=None, motion=False, prio=1):
        return await asyncio.wrap_future(self.submit(fn, what, motion, prio))

    def request_stop(self):
        """STOP (from the event loop): cut the job under way short, cancel every queued
        motion, and broadcast moving speed 0 before anything else. The Future of the
        broadcast's job (its result: the time it was sent)."""
        if self.bus is None:
            raise BusGone("The bus is gone (%s): STOP cannot reach the servos — switch "
                          "their power off if one moves." % self.gone_cause)
        self.stop_event.set()
        self.queue.cancel(lambda job: job.motion, Refused(
            "Cancelled by STOP before it was sent: nothing of it was sent.", 409))
        return self.submit(self._stop, "STOP: moving speed 0 to every servo (broadcast)",
                           prio=0)

    def _stop(self, bus):
        bus.stop_all_now()  # not cut short by stop_event, not waiting for a late answer
        at = time.monotonic()
        self.stop_event.clear()
        sid = self.selected
        if sid is not None:  # the selected servo again, with an answer that confirms it
            self.queue.put(Job(lambda b: b.stop(sid), "ID %d: moving speed 0 (STOP, "
                               "confirmed by its answer)" % sid, prio=0))
        if self.held:  # a group move STOP cut short: no goal left for a later ACTION
            self.queue.put(Job(lambda b: self.unhold(b, set(self.held)), "IDs %s: held "
                               "goal replaced (STOP)" % ", ".join(map(str, sorted(
                                   self.held))), prio=0))
        return at

    def unhold(self, bus, ids):
        """Replace what servos ids may hold from a REG WRITE of the studio's (a group move
        cut short between its REG WRITEs and its ACTION) by a REG WRITE that changes
        nothing — register 49 as it is — so that a later broadcast ACTION does not start
        an old move (a held write survives STOP: PROTOCOL.md §4.4). Worker thread. The
        IDs that did not answer (they may still hold it)."""
        left = []
        for sid in sorted(ids):
            try:
                value = bus.read(sid, "move_without_reference")
                bus.reg_write(sid, {"move_without_reference": value})
                self.held.discard(sid)
            except Interrupted:
                raise
            except ServoBusError as e:
                if is_link_error(e):
                    raise
                left.append(sid)
        return left

    def _run(self, job):
        """Run one job; its log entry (if it has words) once it is done, dated when it
        ran, saying whether anything was sent."""
        if not job.future.set_running_or_notify_cancel():
            return
        bus = self.bus
        before, start = bus.packets_sent, time.monotonic()
        self.running = job
        try:
            result = job.fn(bus)
        except BaseException as e:  # noqa: B036 (handed to the waiting request)
            self.running = None
            if job.what:
                sent = bus.packets_sent != before
                self.commands += sent
                self.log("%s%s — %s" % ("" if sent else "not sent: ", job.what,
                                        in_words(e)), ok=False, at=start)
            job.future.set_exception(e)
            if is_link_error(e):
                self._lost(e)
            return
        self.running = None
        if job.what and bus.packets_sent != before:
            self.commands += 1
            self.log(job.what, at=start)
        job.future.set_result(result)

    # ---- the worker thread -----------------------------------------------------------

    def _work(self):
        period = 1.0 / SAMPLE_HZ
        next_sample = time.monotonic()
        while not self.stopping:
            if self.bus is None:
                self._reconnect()
                continue
            polling = self.selected is not None or self.live.active()
            wait = max(0.0, next_sample - time.monotonic()) if polling else 0.5
            job = self.queue.get(wait)
            if job is not None:
                self._run(job)
                continue
            now = time.monotonic()
            if polling and now >= next_sample:
                next_sample = max(next_sample + period, now - period)
                next_sample = self._sample(self.selected, now, next_sample)

    def _sample(self, sid, now, next_sample):
        """One live sample (and the table when due), then the dashboard and the register
        plot; the time of the next one. The selected servo not answering does not stop
        the others being read (before, it froze the dashboard and the plot of all)."""
        quiet = False
        try:
            try:
                if sid is not None:
                    sampler.sample(self, sid)
                    self._stamps = [t for t in self._stamps if t > now - 1.0] + [now]
                    self.rate = len(self._stamps) / min(1.0, max(now - self.t0, 1e-3))
                    if now >= self.table_due:
                        self.table_due = now + TABLE_PERIOD_S
                        sampler.table(self, sid)
                self._sample_error(None)
            except (ServoBusError, OSError) as e:
                if isinstance(e, Interrupted) or is_link_error(e):
                    raise
                self._sample_error(in_words(e, self.bus.baud))
                quiet = True
            self.live.poll(self.bus)
        except Interrupted:
            pass  # a STOP: its job is next
        except (ServoBusError, OSError) as e:  # OSError: a serial adapter unplugged
            if is_link_error(e):
                self._lost(e)
                return next_sample
            self._sample_error(in_words(e, self.bus.baud))
            quiet = True
        # a servo that does not answer: leave the bus to the user's actions for a while
        return time.monotonic() + 0.5 if quiet else next_sample

    def _sample_error(self, words):
        """The live sample's refusal in words (None: it answers), pushed when it changes."""
        if words != self.sample_error:
            self.sample_error = words
            self.state["sample_error"] = words or ""
            self.changed()

    def wake(self):
        """Let the worker look at what to poll now (a job that does nothing)."""
        self.queue.put(Job(lambda bus: None))

    def _lost(self, e):
        """The bus went away: every queued job is refused (nothing of it is sent), and
        the worker reconnects."""
        try:
            if self.bus is not None:
                self.bus.close()
        except Exception:  # noqa: BLE001 (closing a broken link)
            pass
        self.bus = None
        self.stop_event.clear()
        self._gone(e)
        self.state["link_ok"] = False
        self.queue.cancel(lambda job: True, BusGone(
            "The bus went away before this was sent (%s): nothing of it was sent." % e))
        self.log("lost the bus: %s" % e, ok=False)

    def _gone(self, e):
        """Say why the bus is gone: the header's sentence, and the cause alone for the
        refusals, which begin "The bus is gone" themselves (never twice)."""
        self.gone_cause = " ".join(str(e).split()).rstrip(".")
        self.state["link"] = "%s — reconnecting" % in_words(e).rstrip(".")

    def _reconnect(self):
        time.sleep(RECONNECT_S)
        try:
            bus = Bus(self.port, baud=self.state["baud"])
        except (ServoBusError, OSError) as e:
            self._gone(e)
            self.changed()
            return
        self._own(bus)
        self.bus = bus
        self.state["link"] = "connected"
        self.state["link_ok"] = True
        self.table_due = 0.0
        self.log("reconnected to %s" % self.port)

    def set_resolution(self, sid, value):
        """Servo sid's angle resolution (register 13) is value now: every degree the
        studio converts for it uses it from the next action on (before, a group move
        right after a change sent its goal at the old resolution: half the angle)."""
        res = value or 10
        self.resolutions[sid] = res
        if sid == self.selected:
            self.resolution = res

    def renumbered(self, sid, new):
        """Servo sid answers at ID new now (Set ID, a restore with the ID): the list and
        the per-servo state follow it. Call from the event loop."""
        for s in self.state["servos"]:
            if s["id"] == sid:
                s["id"] = new
        self.state["servos"].sort(key=lambda s: s["id"])
        if sid in self.resolutions:
            self.resolutions[new] = self.resolutions.pop(sid)
        if sid in self.held:  # what it holds went with it
            self.held.discard(sid)
            self.held.add(new)

    def follow_baud(self, bus, sid, code, variant=None):
        """Servo sid (of variant, default: as the Bus knows it) answers at baud code from
        now on (worker thread): on a serial bus the host follows it, as after a write of
        baud_rate."""
        if bus.is_tcp:
            return
        baud = baud_of_code(code, variant or bus.variant(sid))
        bus.set_baud(baud)
        self.state["baud"] = baud
        for s in self.state["servos"]:
            if s["id"] == sid:
                s["heard_baud"] = s["baud"] = baud

    def select(self, sid):
        """The job that makes sid the servo every panel shows."""
        def job(bus):
            entry = next((s for s in self.state["servos"] if s["id"] == sid), None)
            if entry and entry["heard_baud"] != bus.baud and not bus.is_tcp:
                bus.set_baud(entry["heard_baud"])
                self.state["baud"] = bus.baud
            self.variant = variant_by_model(bus.read(sid, "model_number"))
            self.resolution = bus.read(sid, "angle_resolution") or 10
            self.resolutions[sid] = self.resolution
            self.selected = sid
            self.slow = {}
            self.nsample = -1  # the first sample reads the whole block
            self.table_due = 0.0
            return self.variant.name if self.variant else None
        return job
