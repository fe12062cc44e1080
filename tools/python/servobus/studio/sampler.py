"""The live sample and the whole table of the selected servo, decoded for the page (run
in the worker thread)."""

import time

from ..protocol import describe_err
from ..registers import REGISTERS

# Registers in the live sample, one READ: goal (30) to temperature (46); every
# SAMPLE_FULL_EVERY-th sample from homing (24) to move_without_reference (49). At 9600
# baud the short answer takes 25 ms on the wire, the long one 33 ms.
SAMPLE_FAST_FIRST, SAMPLE_FAST_LAST = 30, 46
SAMPLE_FIRST, SAMPLE_LAST = 24, 49
SAMPLE_FULL_EVERY = 4


def sample(self, sid):
    """Read one live sample of servo sid and push it to every tab (self: the Studio)."""
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


def table(self, sid):
    """Read the whole table of servo sid and push it to every tab (self: the Studio)."""
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
    self.resolutions[sid] = self.resolution
    self.push({"type": "table", "id": sid, "values": values,
               "resolution": self.resolution})
