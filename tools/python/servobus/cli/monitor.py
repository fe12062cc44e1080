"""servoctl monitor: live position, speed, temperature and errors, and a plot."""

import sys
import time

from .. import protocol as P
from ..registers import REGISTERS
from .common import PROG


def cmd_monitor(bus, args):
    plt = None
    if args.plot:
        try:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
        except ImportError:
            print("%s: --plot needs matplotlib: apt-get install python3-matplotlib (or pip "
                  "install matplotlib)" % PROG, file=sys.stderr)
            return 1
    bus.raise_faults = False
    pos_reg = bus.position_register(args.id)
    resolution = bus.resolution(args.id)
    speed_reg, temp_reg = REGISTERS["present_speed"], REGISTERS["present_temperature"]
    names = [pos_reg.name, "present_speed", "moving", "present_temperature"]
    samples = []
    start = time.monotonic()
    try:
        while True:
            s = bus.read_many(args.id, names)
            t = time.monotonic() - start
            samples.append((t, s[pos_reg.name], s["present_speed"], s["present_temperature"]))
            errs = bus.last_err & P.ERR_FAULTS
            print("%7.2f s  position %-16s  speed %-20s  moving %d  temperature %-12s  "
                  "errors: %s" % (t, pos_reg.format(s[pos_reg.name], resolution),
                                  speed_reg.format(s["present_speed"], resolution),
                                  s["moving"], temp_reg.format(s["present_temperature"]),
                                  ", ".join(P.describe_err(errs)) if errs else "none"),
                  flush=True)
            if args.count and len(samples) >= args.count:
                break
            if args.duration and t >= args.duration:
                break
            time.sleep(max(0.0, args.interval - (time.monotonic() - start - t)))
    except KeyboardInterrupt:
        pass
    if plt and samples:
        factor = resolution * 0.1
        ts = [x[0] for x in samples]
        fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(8, 5))
        ax1.plot(ts, [x[1] * factor for x in samples])
        ax1.set_ylabel("position (deg)")
        ax2.plot(ts, [x[2] * factor for x in samples], color="tab:orange")
        ax2.set_ylabel("speed (deg/s)")
        ax2.set_xlabel("time (s)")
        ax1.set_title("ID %d on %s" % (args.id, bus.port))
        fig.tight_layout()
        fig.savefig(args.plot)
        print("plot written to %s" % args.plot)
    return 0
