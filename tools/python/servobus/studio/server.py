"""The studio's server: aiohttp for the page, a JSON API for actions and a WebSocket that
pushes the shared state, live samples and the control table to every open tab.

One worker thread owns the Bus: actions are jobs in its queue (STOP jumps the queue),
and between jobs it samples the selected servo at SAMPLE_HZ and reads its whole table
every TABLE_PERIOD_S. Only the Bus's public API and the registers module are used."""

import asyncio
import concurrent.futures
import fcntl
import itertools
import json
import os
import queue
import re
import sys
import tempfile
import threading
import time

from aiohttp import WSMsgType, web

from .. import (BROADCAST, VARIANTS, Bus, BusTimeout, IdTaken, ImageError, RangeError,
                ServoBusError, UnknownRegister)
from ..protocol import describe_err
from ..registers import (BAUD_RATES, REGISTERS, UNIT_TEXT, baud_of_code, register,
                         variant_by_model)

STATIC = os.path.join(os.path.dirname(os.path.abspath(__file__)), "static")
# Debian's libjs-chart.js, served from where the package installs it.
CHART_JS = os.environ.get("STUDIO_CHART_JS",
                          "/usr/share/javascript/chart.js/chart.min.js")
SAMPLE_HZ = 30            # live samples per second at most (the plot needs >= 20)
TABLE_PERIOD_S = 1.0      # whole control table of the selected servo
RESCAN_AFTER_S = 5.0      # a page opened later than this after the last scan rescans
LOG_KEEP = 200
# Registers in the live sample, one READ: goal (30) to temperature (46); every
# SAMPLE_FULL_EVERY-th sample from homing (24) to move_without_reference (49). At 9600
# baud the short answer takes 25 ms on the wire, the long one 33 ms.
SAMPLE_FAST_FIRST, SAMPLE_FAST_LAST = 30, 46
SAMPLE_FIRST, SAMPLE_LAST = 24, 49
SAMPLE_FULL_EVERY = 4


def lock_path(port):
    """The lock file that makes one studio process own one bus."""
    safe = re.sub(r"[^A-Za-z0-9]+", "_", port).strip("_")
    return os.path.join(tempfile.gettempdir(), "servobus-studio-%s.lock" % safe)


class PortInUse(Exception):
    pass


def take_port(port, url):
    """Hold the port's lock for this process's life; PortInUse says who has it."""
    path = lock_path(port)
    f = open(path, "a+")
    try:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        f.seek(0)
        who = f.read().strip() or "another process"
        f.close()
        raise PortInUse("port %s is in use: %s already owns it. Open that studio in your "
                        "browser, or stop it first (one program at a time drives a bus)"
                        % (port, who)) from None
    f.seek(0)
    f.truncate()
    f.write("Servo Studio (process %d, %s)" % (os.getpid(), url))
    f.flush()
    return f


def is_link_error(e):
    """The connection to the bus itself failed (as opposed to one servo's answer)."""
    if isinstance(e, OSError):
        return True
    return type(e) is ServoBusError and bool(re.search(
        r"connect|closed the connection|cannot open|lost the", str(e)))


def in_words(e, baud=None):
    """An exception as a sentence for the page."""
    text = str(e)
    if isinstance(e, BusTimeout):
        sid = getattr(e, "servo_id", None)
        who = "ID %d" % sid if sid is not None else "the servo"
        return ("No answer from %s%s: no servo with that ID, the wrong baud rate, or power "
                "and wiring. (%s)" % (who, " at %d baud" % baud if baud else "", text))
    if is_link_error(e):
        if "closed the connection" in text:
            return ("Bus busy: the port %s — another program is connected to it" %
                    text.split(" closed")[0])
        return "The bus is gone: %s" % text
    return text


def register_info():
    """The control table for the page (from registers.json via the registers module)."""
    out = []
    for r in REGISTERS.values():
        lo, hi = r.value_range()
        out.append({
            "address": r.address, "name": r.name, "size": r.size, "access": r.access,
            "area": r.area, "variants": list(r.variants), "min": lo, "max": hi,
            "unit": r.unit or "", "unit_text": UNIT_TEXT.get(r.unit, ""), "doc": r.doc,
            "default": r.default,
        })
    return out


class Studio:
    """The shared state and the worker thread that owns the Bus."""

    def __init__(self, bus, url):
        self.bus = bus
        self.port = bus.port
        self.url = url
        bus.raise_faults = False  # fault bits are shown, not raised
        self.t0 = time.monotonic()
        self.loop = None
        self.clients = set()
        self.jobs = queue.PriorityQueue()
        self.seq = itertools.count()
        self.stopping = False
        self.selected = None
        self.variant = None
        self.resolution = 10
        self.busy = None            # what holds the bus for a while (scan, update)
        self.sample_error = None
        self.rate = 0.0
        self.last_scan = None
        self.table_due = 0.0
        self.commands = 0           # instructions the user's actions sent
        self.nsample = 0
        self.slow = {}              # homing and photo switches from the last full sample
        self.state = {
            "port": bus.port, "baud": bus.baud, "tcp": bus.is_tcp, "link": "connected",
            "link_ok": True, "servos": [], "selected": None, "busy": None,
            "scan": {"running": False, "done": 0, "total": 0, "baud": None,
                     "notes": [], "warning": "", "message": ""},
            "update": {"running": False, "id": None, "done": 0, "total": 0, "bytes": 0,
                       "bytes_total": 0, "before": None, "after": None, "error": "",
                       "note": "", "file": ""},
            "log": [], "commands": 0, "sample_error": "", "rate": 0.0,
        }
        self.thread = threading.Thread(target=self._work, name="studio-bus", daemon=True)

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

    def log(self, text, ok=True):
        self.state["log"].append({"t": round(time.monotonic() - self.t0, 1), "text": text,
                                  "ok": ok})
        del self.state["log"][:-LOG_KEEP]
        self.changed()

    # ---- the worker -----------------------------------------------------------------

    def submit(self, fn, prio=1):
        fut = concurrent.futures.Future()
        self.jobs.put((prio, next(self.seq), fn, fut))
        return fut

    async def call(self, fn, prio=1):
        return await asyncio.wrap_future(self.submit(fn, prio))

    def _work(self):
        period = 1.0 / SAMPLE_HZ
        next_sample = time.monotonic()
        stamps = []
        while not self.stopping:
            if self.bus is None:
                self._reconnect()
                continue
            wait = max(0.0, next_sample - time.monotonic()) if self.selected is not None \
                else 0.5
            try:
                _, _, fn, fut = self.jobs.get(timeout=wait)
            except queue.Empty:
                fn = None
            if fn is not None:
                if not fut.set_running_or_notify_cancel():
                    continue
                try:
                    fut.set_result(fn(self.bus))
                except BaseException as e:  # noqa: B036 (handed to the waiting request)
                    fut.set_exception(e)
                    if is_link_error(e):
                        self._lost(e)
                continue
            sid = self.selected
            now = time.monotonic()
            if sid is None or now < next_sample:
                continue
            next_sample = max(next_sample + period, now - period)
            try:
                self._sample(sid)
                stamps.append(now)
                stamps = [s for s in stamps if s > now - 1.0]
                self.rate = len(stamps) / min(1.0, max(now - self.t0, 1e-3))
                if now >= self.table_due:
                    self.table_due = now + TABLE_PERIOD_S
                    self._table(sid)
                if self.sample_error:
                    self.sample_error = None
                    self.state["sample_error"] = ""
                    self.changed()
            except (ServoBusError, OSError) as e:  # OSError: a serial adapter unplugged
                if is_link_error(e):
                    self._lost(e)
                    continue
                words = in_words(e, self.bus.baud)
                if words != self.sample_error:
                    self.sample_error = words
                    self.state["sample_error"] = words
                    self.changed()
                next_sample = time.monotonic() + 0.5  # leave the bus to the user's actions

    def _lost(self, e):
        try:
            if self.bus is not None:
                self.bus.close()
        except Exception:  # noqa: BLE001 (closing a broken link)
            pass
        self.bus = None
        self.state["link"] = "%s — reconnecting" % in_words(e)
        self.state["link_ok"] = False
        self.log("lost the bus: %s" % e, ok=False)

    def _reconnect(self):
        time.sleep(0.5)
        try:
            bus = Bus(self.port, baud=self.state["baud"])
            bus.raise_faults = False
        except (ServoBusError, OSError) as e:
            self.state["link"] = "%s — reconnecting" % in_words(e)
            self.changed()
            return
        self.bus = bus
        self.state["link"] = "connected"
        self.state["link_ok"] = True
        self.table_due = 0.0
        self.log("reconnected to %s" % self.port)

    def _sample(self, sid):
        bus = self.bus
        self.nsample += 1
        first, last = (SAMPLE_FIRST, SAMPLE_LAST) if self.nsample % SAMPLE_FULL_EVERY == 0 \
            else (SAMPLE_FAST_FIRST, SAMPLE_FAST_LAST)
        data = bus.read_raw(sid, first, last - first + 1)
        err = bus.last_err
        v = {}
        for r in REGISTERS.values():
            if first <= r.address and r.address + r.size <= last + 1 and \
                    r.readable and r.applies_to(self.variant):
                off = r.address - first
                v[r.name] = r.decode(int.from_bytes(data[off:off + r.size], "little"))
        deg = self.resolution * 0.1
        pos_reg = "present_position" if "present_position" in v else "turned_angle"
        self.slow.update({k: v[k] for k in ("homing", "sleep", "photo_switches") if k in v})
        homing = self.slow.get("homing", 0)
        self.push({
            "type": "sample", "id": sid, "t": round(time.monotonic() - self.t0, 3),
            "position": round(v.get(pos_reg, 0) * deg, 2),
            "goal": round(v.get("goal_position", 0) * deg, 2),
            "speed": round(v.get("present_speed", 0) * deg, 2),
            "temperature": v.get("present_temperature"),
            "load": None,  # no present-load register in this firmware's table
            "moving": v.get("moving", 0), "brake": v.get("brake", 0),
            "sleep": self.slow.get("sleep", 0), "photo": self.slow.get("photo_switches", 0),
            "homing_state": homing >> 4,
            "homing": {0: "never run", 1: "running", 2: "done", 3: "failed or aborted"}
            .get(homing >> 4, "state %d" % (homing >> 4)),
            "err": err, "err_words": describe_err(err), "rate": round(self.rate, 1),
            "regs": v,  # for the control table's live values
        })

    def _table(self, sid):
        bus = self.bus
        data = bus.read_raw(sid, 0, 50)
        values = {}
        for r in REGISTERS.values():
            if not r.readable or not r.applies_to(self.variant):
                values[r.name] = None
                continue
            values[r.name] = r.decode(int.from_bytes(data[r.address:r.address + r.size],
                                                     "little"))
        self.resolution = values.get("angle_resolution") or 10
        self.push({"type": "table", "id": sid, "values": values,
                   "resolution": self.resolution})

    # ---- actions (run in the worker) ------------------------------------------------

    def scan_at(self, bus, baud):
        start = bus.baud
        try:
            if baud != bus.baud:
                bus.set_baud(baud)
            found = bus.scan()
            return found, list(bus.scan_notes)
        finally:
            if bus.baud != start:
                bus.set_baud(start)

    def details(self, bus, f):
        start = bus.baud
        try:
            if f.baud != bus.baud:
                bus.set_baud(f.baud)
            v = bus.read_many(f.id, ["model_number", "firmware_version", "baud_rate"])
        finally:
            if bus.baud != start:
                bus.set_baud(start)
        variant = variant_by_model(v["model_number"])
        return {
            "id": f.id, "heard_baud": f.baud, "model": v["model_number"],
            "model_hex": "0x%04X" % v["model_number"],
            "variant": variant.name if variant else "unknown model",
            "firmware": v["firmware_version"],
            "baud": baud_of_code(v["baud_rate"], variant), "err": f.err,
            "health": describe_err(f.err),
        }

    def select(self, sid):
        """Make sid the servo every panel shows (in the worker)."""
        def job(bus):
            entry = next((s for s in self.state["servos"] if s["id"] == sid), None)
            if entry and entry["heard_baud"] != bus.baud and not bus.is_tcp:
                bus.set_baud(entry["heard_baud"])
                self.state["baud"] = bus.baud
            self.variant = variant_by_model(bus.read(sid, "model_number"))
            self.resolution = bus.read(sid, "angle_resolution") or 10
            self.selected = sid
            self.slow = {}
            self.nsample = -1  # the first sample reads the whole block
            self.table_due = 0.0
            return self.variant.name if self.variant else None
        return job


# ---- HTTP -------------------------------------------------------------------------

def ok(**kw):
    return web.json_response(dict(ok=True, **kw))


def refuse(text):
    return web.json_response({"ok": False, "error": text})


def routes(st):
    r = web.RouteTableDef()

    @r.get("/")
    async def index(_):
        return web.FileResponse(os.path.join(STATIC, "index.html"))

    @r.get("/favicon.ico")
    async def favicon(_):
        return web.Response(status=204)

    @r.get("/chart.js")
    async def chart(_):
        if not os.path.exists(CHART_JS):
            return web.Response(
                status=404, content_type="application/javascript",
                text="window.CHART_MISSING = %s;" % json.dumps(
                    "%s is missing: install Debian's libjs-chart.js "
                    "(tools/install-deps.sh)" % CHART_JS))
        return web.FileResponse(CHART_JS)

    @r.get("/api/registers")
    async def registers(_):
        return web.json_response({
            "registers": register_info(), "bauds": BAUD_RATES, "units": UNIT_TEXT,
            "variants": {v.name: {"photo_switches": v.photo_switches,
                                  "model": v.model_number,
                                  "max_angle_deg": v.max_angle_ddeg / 10}
                         for v in VARIANTS.values()}})

    @r.get("/ws")
    async def ws_handler(request):
        ws = web.WebSocketResponse(heartbeat=20)
        await ws.prepare(request)
        st.clients.add(ws)
        await ws.send_str(json.dumps({"type": "state", "state": st.state}))
        if not st.busy and (st.last_scan is None or
                            time.monotonic() - st.last_scan > RESCAN_AFTER_S):
            asyncio.ensure_future(do_scan(st, False))  # opening the app scans
        try:
            async for msg in ws:
                if msg.type == WSMsgType.ERROR:
                    break
        finally:
            st.clients.discard(ws)
        return ws

    async def action(request, fn, need_servo=True, while_busy=False):
        try:
            body = await request.json() if request.can_read_body else {}
        except ValueError:
            return refuse("the request was not JSON")
        if st.busy and not while_busy:
            return refuse("The bus is busy: %s. Try again when it is done." % st.busy)
        sid = body.get("id", st.selected)
        if need_servo:
            if sid is None:
                return refuse("No servo selected: scan, then pick one in the list.")
            sid = int(sid)
        try:
            return await fn(body, sid)
        except (RangeError, UnknownRegister, IdTaken, ImageError) as e:
            st.log("refused: %s" % e, ok=False)
            return refuse(in_words(e))
        except (ServoBusError, OSError) as e:
            words = in_words(e, st.bus.baud if st.bus else None)
            st.log(words, ok=False)
            return refuse(words)

    def sent(text):
        st.commands += 1
        st.log(text)

    @r.post("/api/scan")
    async def scan(request):
        async def go(body, _):
            if st.busy:
                return refuse("The bus is busy: %s." % st.busy)
            asyncio.ensure_future(do_scan(st, bool(body.get("all")), body.get("baud")))
            return ok()
        return await action(request, go, need_servo=False)

    @r.post("/api/select")
    async def select(request):
        async def go(_, sid):
            name = await st.call(st.select(sid))
            st.changed()
            return ok(variant=name)
        return await action(request, go)

    @r.post("/api/write")
    async def write(request):
        async def go(body, sid):
            reg = register(body["name"])
            if not reg.writable:
                return refuse("%s is read-only." % reg.name)
            if not reg.applies_to(st.variant):
                return refuse("%s does not exist on the %s." % (reg.name, st.variant.name))
            value = reg.parse(body["value"], st.resolution)  # RangeError: nothing sent
            if reg.name == "id":
                return refuse("Change the ID in the ID & reset panel: it checks that the "
                              "new ID is free first.")

            def job(bus):
                bus.write(sid, reg.name, value)
                if reg.name == "baud_rate" and not bus.is_tcp:
                    # the servo answers at its new baud from now on: follow it
                    baud = baud_of_code(value, st.variant)
                    bus.set_baud(baud)
                    st.state["baud"] = baud
                    for s in st.state["servos"]:
                        if s["id"] == sid:
                            s["heard_baud"] = s["baud"] = baud
                return bus.read(sid, reg.name) if reg.readable else value
            sent("ID %d: WRITE %s = %s" % (sid, reg.name, value))
            now = await st.call(job)
            st.table_due = 0.0
            return ok(value=now)
        return await action(request, go)

    @r.post("/api/stop")
    async def stop(request):
        async def go(_, sid):
            def job(bus):
                bus.write(BROADCAST, "moving_speed", 0, check_variant=False)
                if sid is not None:
                    bus.stop(sid)
            sent("STOP: moving speed 0 to every servo (broadcast)%s" % (
                "" if sid is None else " and to ID %d" % sid))
            await st.call(job, prio=0)
            return ok()
        return await action(request, go, need_servo=False, while_busy=True)

    def units(deg):
        return int(round(float(deg) / (st.resolution * 0.1)))

    @r.post("/api/move")
    async def move(request):
        async def go(body, sid):
            goal, speed = units(body["goal"]), units(body["speed"])
            acc, dec = int(body.get("acc", 36)), int(body.get("dec", 36))
            if not 0 <= goal <= 0xFFFF:
                return refuse("Goal %s deg is outside 0..%g deg." % (
                    body["goal"], 0xFFFF * st.resolution * 0.1))
            if not 1 <= speed <= 0x7FFF:
                return refuse("Speed must be above 0 and at most %g deg/s." % (
                    0x7FFF * st.resolution * 0.1))
            for name, v in (("acceleration", acc), ("deceleration", dec)):
                if not 0 <= v <= 255:
                    return refuse("The %s %d is outside 0..255 (x10 deg/s^2)." % (name, v))
            sent("ID %d: move to %s deg at %s deg/s (acc %d, dec %d)" % (
                sid, body["goal"], body["speed"], acc, dec))

            def job(bus):
                if REGISTERS["acceleration"].applies_to(st.variant):
                    # goal, speed, acceleration, deceleration (30-35) in one WRITE, so the
                    # goal register (and the plot) shows the target
                    bus.write(sid, {"goal_position": goal, "moving_speed": speed,
                                    "acceleration": acc, "deceleration": dec})
                else:  # the base: ramps are EEPROM registers, CUSTOM MOVE carries them
                    bus.move_absolute(sid, goal, speed, acc, dec)
            await st.call(job)
            return ok()
        return await action(request, go)

    @r.post("/api/speed")
    async def speed(request):
        async def go(body, sid):
            v = units(body["speed"])
            if abs(v) > 0x7FFF:
                return refuse("Speed %s deg/s is too fast." % body["speed"])

            def job(bus):
                if v and REGISTERS["acceleration"].applies_to(st.variant):  # not the base
                    lim = bus.read_many(sid, ["cw_angle_limit", "ccw_angle_limit"])
                    if lim["cw_angle_limit"] or lim["ccw_angle_limit"]:
                        return ("ID %d is in position mode (angle limits %d and %d): a "
                                "speed there is only the cruise speed of the next move. "
                                "For speed mode set cw_angle_limit and ccw_angle_limit to "
                                "0 in the control table." % (
                                    sid, lim["cw_angle_limit"], lim["ccw_angle_limit"]))
                bus.set_speed(sid, v)
                return None
            refused = await st.call(job)
            if refused:
                st.log(refused, ok=False)
                return refuse(refused)
            sent("ID %d: speed mode at %s deg/s" % (sid, body["speed"]))
            return ok()
        return await action(request, go)

    @r.post("/api/home")
    async def home(request):
        async def go(body, sid):
            start = bool(body.get("start", True))
            sent("ID %d: %s homing" % (sid, "start" if start else "stop"))
            await st.call(lambda bus: bus.home(sid) if start else bus.stop_homing(sid))
            return ok()
        return await action(request, go)

    @r.post("/api/traj")
    async def traj(request):
        async def go(body, sid):
            points = []
            for n, (a, s) in enumerate(body["points"], 1):
                try:
                    points.append((units(a), units(s)))
                except (TypeError, ValueError):
                    return refuse("Point %d: '%s', '%s' are not numbers." % (n, a, s))
            if not points:
                return refuse("The trajectory has no points.")
            sent("ID %d: trajectory of %d points, run" % (sid, len(points)))

            def job(bus):
                bus.trajectory_write(sid, points)
                bus.trajectory_action(sid)
            await st.call(job)
            return ok()
        return await action(request, go)

    @r.post("/api/setid")
    async def setid(request):
        async def go(body, sid):
            new = int(body["new_id"])
            if not 0 <= new <= 253:
                return refuse("ID %d is outside 0..253." % new)
            taken = [s for s in st.state["servos"] if s["id"] == new and new != sid]
            if taken:
                return refuse("ID %d is taken by the %s on this bus: choose another ID." % (
                    new, taken[0]["variant"]))
            sent("ID %d: set ID to %d" % (sid, new))
            await st.call(lambda bus: bus.set_id(sid, new))
            for s in st.state["servos"]:
                if s["id"] == sid:
                    s["id"] = new
            st.state["servos"].sort(key=lambda s: s["id"])
            await st.call(st.select(new))
            st.changed()
            return ok(id=new)
        return await action(request, go)

    @r.post("/api/reset")
    async def reset(request):
        async def go(_, sid):
            sent("ID %d: factory reset" % sid)
            await st.call(lambda bus: bus.reset(sid))
            st.selected = None
            st.changed()
            asyncio.ensure_future(do_scan(st, False))
            return ok()
        return await action(request, go)

    @r.post("/api/update")
    async def update(request):
        if st.busy:
            return refuse("The bus is busy: %s." % st.busy)
        try:
            sid = int(request.query["id"])
        except (KeyError, ValueError):
            return refuse("Give the ID of the servo to update.")
        if not 0 <= sid <= 253:
            return refuse("ID %d is outside 0..253." % sid)
        data = await request.read()
        name = request.query.get("file", "the image")
        if not data:
            return refuse("Choose a firmware file first.")
        asyncio.ensure_future(do_update(st, sid, data, name))
        return ok()

    @r.post("/api/clear")
    async def clear_log(_):
        st.state["log"] = []
        st.changed()
        return ok()

    return r


async def do_scan(st, all_bauds, baud=None):
    """Scan at the bus baud, at one baud, or at every baud, with progress."""
    if st.busy:
        return  # a scan asked for twice (a page opening while one was scheduled)
    sc = st.state["scan"]
    bus_baud = st.state["baud"]
    if all_bauds and st.state["tcp"]:
        bauds = [bus_baud]
        notes = ["over tcp:// every servo hears every baud: one scan covers all eleven "
                 "baud codes"]
    elif all_bauds:
        bauds = list(BAUD_RATES)
        notes = []
    else:
        bauds = [int(baud) if baud else bus_baud]
        notes = []
    st.busy = "scanning"
    sc.update(running=True, done=0, total=len(bauds), baud=bauds[0], notes=notes,
              warning="", message="")
    st.changed()
    found = {}
    seen_at = {}
    try:
        for i, b in enumerate(bauds):
            sc.update(done=i, baud=b)
            st.changed()
            res, n = await st.call(lambda bus, b=b: st.scan_at(bus, b))
            sc["notes"] += n
            for f in res:
                seen_at.setdefault(f.id, []).append(f.baud)
                found.setdefault(f.id, f)
        servos = []
        for f in found.values():
            try:
                servos.append(await st.call(lambda bus, f=f: st.details(bus, f)))
            except ServoBusError as e:
                if is_link_error(e):
                    raise
                servos.append({"id": f.id, "heard_baud": f.baud, "model": None,
                               "model_hex": "", "variant": "?", "firmware": None,
                               "baud": f.baud, "err": f.err, "health":
                               describe_err(f.err) + ["does not answer READ: %s" % e]})
        servos.sort(key=lambda s: s["id"])
        st.state["servos"] = servos
        dups = sorted({i for i, b in seen_at.items() if len(b) > 1})
        garbled = [x for x in sc["notes"] if "two servos" in x]
        if dups or garbled:
            sc["warning"] = (
                "Duplicate ID? %s Two servos with one ID answer on top of each other: "
                "connect one of them alone and give it a free ID (ID & reset)." % (
                    "ID %s answered at more than one baud." % ", ".join(map(str, dups))
                    if dups else "Garbled answers arrived during the scan."))
        where = "every baud" if all_bauds and not st.state["tcp"] else "%d baud" % bauds[0]
        sc["message"] = ("%d servo%s found at %s." % (len(servos), "" if len(servos) == 1
                                                        else "s", where) if servos else
                         "No servo answered at %s: check power and wiring%s." % (
                             where, "" if all_bauds else ", or scan all baud rates"))
        st.log("scan at %s: %s" % (where, ", ".join(
            "ID %d %s" % (s["id"], s["variant"]) for s in servos) or "nothing"))
        sc["done"] = len(bauds)
        if st.selected not in [s["id"] for s in servos]:
            st.selected = None
        if st.selected is None and servos:
            await st.call(st.select(servos[0]["id"]))
    except (ServoBusError, OSError) as e:
        sc["message"] = in_words(e)
        st.log("scan: %s" % e, ok=False)
    finally:
        st.last_scan = time.monotonic()
        st.busy = None
        sc["running"] = False
        st.changed()


async def do_update(st, sid, data, name):
    up = st.state["update"]
    up.update(running=True, id=sid, done=0, total=0, bytes=0, bytes_total=len(data),
              before=None, after=None, error="", note="", file=name)
    st.busy = "updating the firmware of ID %d" % sid
    st.commands += 1
    st.log("ID %d: firmware update from %s (%d bytes)" % (sid, name, len(data)))

    def progress(done, total, nbytes, total_bytes):
        up.update(done=done, total=total, bytes=nbytes, bytes_total=total_bytes)
        st.changed()

    def note(text):
        up["note"] = text
        st.changed()

    def job(bus):
        if bus.present(sid):
            up["before"] = bus.read(sid, "firmware_version")
        else:
            up["before"] = "none (update mode)"
        st.changed()
        return bus.update(sid, data, progress=progress, notify=note)
    try:
        up["after"] = await st.call(job)
        st.log("ID %d now runs firmware version %s" % (sid, up["after"]))
        for s in st.state["servos"]:
            if s["id"] == sid:
                s["firmware"] = up["after"]
    except (ServoBusError, ImageError, OSError) as e:
        up["error"] = in_words(e)
        st.log("update of ID %d: %s" % (sid, e), ok=False)
    finally:
        up["running"] = False
        st.busy = None
        st.table_due = 0.0
        st.changed()


def _parse_listen(text):
    host, sep, port = text.rpartition(":")
    if not sep or not port.isdigit():
        raise ValueError("--listen '%s': expected HOST:PORT, e.g. 127.0.0.1:8080" % text)
    return host or "127.0.0.1", int(port)


def serve(bus, listen):
    """Run the studio on `listen` with `bus` until Ctrl-C or SIGTERM. Exit status: 0,
    1 port in use or a dead bus, 2 a bad --listen."""
    try:
        host, hport = _parse_listen(listen)
    except ValueError as e:
        print("servoctl studio: %s" % e, file=sys.stderr)
        return 2
    url = "http://%s:%d/" % (host, hport)
    try:
        lock = take_port(bus.port, url)
    except PortInUse as e:
        print("servoctl studio: %s" % e, file=sys.stderr)
        return 1
    st = Studio(bus, url)
    try:
        return asyncio.run(_main(st, host, hport, url))
    except KeyboardInterrupt:
        return 0
    finally:
        lock.close()


PROBE_ID = 253  # any ID: the probe only needs the bus to carry a request


def _probe(st):
    """Before the address is printed: a PING that proves the bus is ours (servo-sim
    closes a second client at once). None, or what is wrong in words. The scan comes
    when the page opens."""
    bus = st.bus
    saved = bus.timeout
    bus.timeout = 0.2
    try:
        bus.ping(PROBE_ID)
    except BusTimeout:
        pass  # nobody at that ID: the usual answer
    except (ServoBusError, OSError) as e:
        if "closed the connection" in str(e):
            return ("port %s is in use: another program is connected to it (servo-sim "
                    "serves one client at a time); stop it first" % bus.port)
        if is_link_error(e):
            return in_words(e)
    finally:
        bus.timeout = saved
    return None


async def _main(st, host, port, url):
    import signal
    st.loop = asyncio.get_running_loop()
    app = web.Application(client_max_size=1 << 20)
    app.add_routes(routes(st))
    app.router.add_static("/static/", STATIC)
    runner = web.AppRunner(app, access_log=None)
    await runner.setup()
    try:
        await web.TCPSite(runner, host, port).start()
    except OSError as e:
        print("servoctl studio: cannot listen on %s:%d: %s (another studio? choose "
              "another with --listen)" % (host, port, e.strerror or e), file=sys.stderr)
        await runner.cleanup()
        return 1
    wrong = _probe(st)  # (a page opened meanwhile waits for it: nothing else runs yet)
    if wrong:
        print("servoctl studio: %s" % wrong, file=sys.stderr)
        await runner.cleanup()
        return 1
    st.thread.start()
    print("Servo Studio on %s at %d baud: open %s" % (st.port, st.state["baud"], url),
          flush=True)
    if host not in ("127.0.0.1", "localhost", "::1"):
        print("servoctl studio: warning: listening on %s: anyone who reaches this address "
              "can move the servos (there is no login)" % host, file=sys.stderr, flush=True)
    done = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        st.loop.add_signal_handler(sig, done.set)
    await done.wait()
    st.stopping = True
    for ws in list(st.clients):
        await ws.close()
    await runner.cleanup()
    st.thread.join(timeout=2)
    return 0
