#!/usr/bin/env python3
"""Plot a move traced by motion_trace --csv: position and speed against the ideal
trapezoid. Usage: plot_motion.py TRACE.csv OUT.png (needs python3-matplotlib)."""
import csv
import sys


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: plot_motion.py TRACE.csv OUT.png")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        sys.exit("plot_motion.py: needs matplotlib (apt-get install python3-matplotlib)")
    with open(sys.argv[1], newline="") as f:
        rows = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]
    t = [r["t"] for r in rows]
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
    ax1.plot(t, [r["ideal_pos"] for r in rows], "k--", label="ideal trapezoid")
    ax1.plot(t, [r["ref_pos"] for r in rows], label="planner reference")
    ax1.plot(t, [r["pos"] for r in rows], label="measured (host gearmotor model)")
    ax1.set_ylabel("position (deg)")
    ax1.legend(loc="lower right")
    ax2.plot(t, [r["ideal_speed"] for r in rows], "k--", label="ideal")
    ax2.plot(t, [r["speed"] for r in rows], label="measured")
    ax2.set_ylabel("speed (deg/s)")
    ax2.set_xlabel("time (s)")
    ax2.legend(loc="upper right")
    fig.suptitle("Foot: 180 deg at 360 deg/s, acceleration 720, deceleration 360 deg/s^2")
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=80)


if __name__ == "__main__":
    main()
