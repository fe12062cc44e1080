"""Live polling of every servo (issue 29), run by the worker between jobs, after the
selected servo's sample: the dashboard (one READ per servo of registers 36-46: position,
speed, moving, brake, temperature; its ERR byte; every MODE_EVERY_S one READ of 5-13
for the mode, the return delay and the resolution) and the plot of any register (the
picked registers in as few READs as the table allows: servobus/polling.py).

Fair when the bus is slow: every cycle reads every servo once, so every servo gets the
same rate, and when the wire cannot carry the cycle in 1/SAMPLE_HZ they all drop
together. The rate achieved is measured and pushed with the wire's limit for the same
READs (polling.wire_limit_hz), so the page shows both."""

import collections
import time

from .. import Interrupted, ServoBusError
from .. import polling as Poll
from ..protocol import describe_err
from ..registers import REGISTERS, decode_table, variant_by_model
from .words import in_words, is_link_error

DASH_FIRST, DASH_COUNT = 36, 11      # present_position .. present_temperature
MODE_FIRST, MODE_COUNT = 5, 9        # return_delay .. angle_resolution
MODE_EVERY_S = 2.0
RATE_WINDOW_S = 2.0


class Rate:
    """Cycles a second over the last RATE_WINDOW_S."""

    def __init__(self):
        self.stamps = collections.deque()

    def tick(self, now):
        self.stamps.append(now)
        while self.stamps and self.stamps[0] < now - RATE_WINDOW_S:
            self.stamps.popleft()
        if len(self.stamps) < 2:
            return 0.0
        return (len(self.stamps) - 1) / max(self.stamps[-1] - self.stamps[0], 1e-3)


class Live:
    """The dashboard's and the register plot's polling (state of the Studio st)."""

    def __init__(self, st):
        self.st = st
        self.dash_on = False
        self.dash_tabs = set()  # the tabs showing the dashboard
        self.tab_picks = {}    # tab -> {ID: [register names]}: each tab's own traces
        self.picks = {}        # {ID: [register names]}: every tab's, read once
        self.reads = []        # polling.plan_reads(picks)
        self.info = {}         # ID -> {"mode", "resolution", "delay"} from the slow READ
        self.mode_due = {}
        self.dash_rate, self.scope_rate = Rate(), Rate()

    def active(self):
        return self.dash_on or bool(self.reads)

    def set_picks(self, tab, picks, baud):
        """Tab's traces (a tab never replaces another's: each shows its own, and the
        worker reads the registers of every tab's, once); the READs of them all."""
        if picks:
            self.tab_picks[tab] = picks
        else:
            self.tab_picks.pop(tab, None)
        return self._replan(baud)

    def _replan(self, baud):
        merged = {}
        for picks in self.tab_picks.values():
            for sid, names in picks.items():
                have = merged.setdefault(sid, [])
                have += [n for n in names if n not in have]
        self.picks = merged
        self.reads = Poll.plan_reads(merged, baud=baud) if merged else []
        self.scope_rate = Rate()
        return self.reads

    def set_dash(self, tab, on):
        """The dashboard polls while at least one tab shows it."""
        if on:
            self.dash_tabs.add(tab)
        else:
            self.dash_tabs.discard(tab)
        self.dash_on = bool(self.dash_tabs)
        return on

    def drop_tab(self, tab, baud):
        """A tab closed: its traces and its dashboard go with it."""
        self.set_dash(tab, False)
        if self.tab_picks.pop(tab, None) is not None:
            self._replan(baud)

    def ids(self):
        return [s["id"] for s in self.st.state["servos"]]

    def poll(self, bus):
        """One cycle (worker thread): the dashboard, then the picked registers."""
        if self.dash_on:
            self._dash(bus)
        if self.reads:
            self._scope(bus)

    def _slow(self, bus, sid, now):
        """The servo's mode, return delay and resolution, every MODE_EVERY_S."""
        if now < self.mode_due.get(sid, 0.0) and sid in self.info:
            return self.info[sid]
        self.mode_due[sid] = now + MODE_EVERY_S
        data = bus.read_raw(sid, MODE_FIRST, MODE_COUNT)
        v = decode_table(data, MODE_FIRST)
        entry = next((s for s in self.st.state["servos"] if s["id"] == sid), {})
        variant = variant_by_model(entry.get("model", -1))
        speed_mode = (variant is not None and variant.name == "base") or (
            v["cw_angle_limit"] == 0 and v["ccw_angle_limit"] == 0)
        self.info[sid] = {"mode": "speed" if speed_mode else "position",
                          "resolution": v["angle_resolution"] or 10,
                          "delay": v["return_delay"] * 0.0005,
                          "variant": variant.name if variant else "?"}
        self.st.resolutions[sid] = self.info[sid]["resolution"]
        return self.info[sid]

    def _dash(self, bus):
        rows, now = [], time.monotonic()
        for sid in self.ids():
            try:
                info = self._slow(bus, sid, now)
                data = bus.read_raw(sid, DASH_FIRST, DASH_COUNT)
                err = bus.last_err
            except Interrupted:
                raise
            except ServoBusError as e:
                if is_link_error(e):
                    raise
                rows.append({"id": sid, "error": in_words(e, bus.baud)})
                continue
            v = decode_table(data, DASH_FIRST)
            deg = info["resolution"] * 0.1
            pos = v["present_position"] if info["variant"] in ("wrist", "finger") \
                else v["turned_angle"]
            rows.append({"id": sid, "variant": info["variant"],
                         "position": round(pos * deg, 2),
                         "speed": round(v["present_speed"] * deg, 2),
                         "temperature": v["present_temperature"], "moving": v["moving"],
                         "brake": v["brake"], "mode": info["mode"], "err": err,
                         "err_words": describe_err(err)})
        reads = [(sid, DASH_FIRST, DASH_COUNT, []) for sid in self.ids()]
        delays = {sid: i["delay"] for sid, i in self.info.items()}
        self.st.push({"type": "dash", "t": round(now - self.st.t0, 3), "rows": rows,
                      "rate": round(self.dash_rate.tick(now), 1),
                      "wire_hz": round(Poll.wire_limit_hz(reads, bus.baud, delays), 1)})

    def _scope(self, bus):
        now = time.monotonic()
        answers = []
        for sid, first, count, _ in self.reads:
            try:
                self._slow(bus, sid, now)  # its resolution and return delay, every 2 s
                answers.append(bus.read_raw(sid, first, count))
            except Interrupted:
                raise
            except ServoBusError as e:
                if is_link_error(e):
                    raise
                answers.append(None)
        variants = {sid: variant_by_model(next((s["model"] for s in self.st.state["servos"]
                                                if s["id"] == sid), -1))
                    for sid in self.picks}
        values = Poll.decode_reads(self.reads, answers, variants)
        out = {}
        for sid, regs in values.items():
            res = self.st.resolutions.get(sid, 10)
            for name, v in regs.items():
                factor = REGISTERS[name].scale(res)[0]
                out["%d.%s" % (sid, name)] = round(v * factor, 3) if factor else v
        delays = {sid: i["delay"] for sid, i in self.info.items()}
        self.st.push({"type": "scope", "t": round(now - self.st.t0, 4), "v": out,
                      "rate": round(self.scope_rate.tick(now), 1),
                      "wire_hz": round(Poll.wire_limit_hz(self.reads, bus.baud, delays), 1),
                      "reads": len(self.reads)})
