#!/usr/bin/env python3
"""make demo: an arm, a foot and a base (the firmware built for the host) on the virtual
servo bus (build/host/servo-sim), driven through the Python SDK in real time: scan, home
the arm, a trapezoidal move, a trajectory, speed mode on the base and a heartbeat stop.
Prints what happens in plain words and writes a PNG plot of position and speed against
time (build/demo.png, or the path given).

--qemu (make demo QEMU=1): the same session against the arm firmware itself, running on
qemu-system-arm (tools/qemu_servo.py, the `qemu` build): one arm, ID 1, so the base's
speed mode and the foot's stop are done by the arm (speed mode: both limits 0)."""
import os
import re
import subprocess
import sys
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "tools", "python"))

from servobus import Bus  # noqa: E402

SIM = os.environ.get("SERVO_SIM") or os.path.join(REPO, "build", "host", "servo-sim")
QEMU = "--qemu" in sys.argv[1:]
ARM, FOOT, BASE = (1, 1, 1) if QEMU else (1, 2, 3)
BASE_NAME, FOOT_NAME = ("arm", "arm") if QEMU else ("base", "foot")


PROBLEMS = []


def say(text):
    print(text, flush=True)


def check(ok, what):
    """The demo is also a test (CTest demo.session): note what did not happen."""
    if not ok:
        PROBLEMS.append(what)
        say("   !! %s" % what)


def start_qemu():
    sys.path.insert(0, os.path.join(REPO, "tools"))
    from qemu_servo import QemuServo
    try:
        q = QemuServo()
    except FileNotFoundError as e:
        sys.exit("demo: %s" % e)
    if not q.wait_ready():
        sys.exit("demo: the QEMU image did not boot: %s" % q.stop())
    return q, q.port


def start_sim():
    if QEMU:
        return start_qemu()
    proc = subprocess.Popen([SIM, "--listen", "127.0.0.1:0", "--servo", "%d:arm" % ARM,
                             "--servo", "%d:foot" % FOOT, "--servo", "%d:base" % BASE],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    m = re.search(r"listening on [\d.]+:(\d+)", line)
    if not m:
        proc.kill()
        sys.exit("demo: servo-sim did not start: %s%s" % (line, proc.stderr.read()))
    return proc, int(m.group(1))


class Recorder:
    """Samples position and speed of some servos while the demo waits (each sample is a
    READ, which also keeps the servos' heartbeat fed)."""

    def __init__(self, bus):
        self.bus = bus
        self.t0 = time.monotonic()
        self.samples = {}  # id -> [(t, position, speed)]

    def sample(self, ids):
        t = time.monotonic() - self.t0
        for i in ids:
            reg = self.bus.position_register(i).name
            v = self.bus.read_many(i, [reg, "present_speed"])
            self.samples.setdefault(i, []).append((t, v[reg], v["present_speed"]))

    def wait(self, seconds, ids, until=None):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.sample(ids)
            if until and until():
                return True
            time.sleep(0.03)
        return False


def plot(rec, path):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        say("(no plot: python3-matplotlib is not installed)")
        return
    names = {FOOT: "foot (deg)", BASE: "base (deg)", ARM: "arm (deg)"}
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(9, 6))
    for i, rows in sorted(rec.samples.items()):
        ax1.plot([r[0] for r in rows], [r[1] for r in rows], ".-", ms=2, label=names[i])
        ax2.plot([r[0] for r in rows], [r[2] for r in rows], ".-", ms=2, label=names[i])
    ax1.set_ylabel("position")
    ax2.set_ylabel("speed (deg/s)")
    ax2.set_xlabel("time (s)")
    ax1.legend(loc="upper left")
    ax2.legend(loc="upper left")
    fig.suptitle("make demo: homing, a move and a trajectory on the arm; base speed mode "
                 "and heartbeat stop")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    say("Plot of position and speed against time: %s" % path)


def main():
    args = [a for a in sys.argv[1:] if a != "--qemu"]
    out_png = args[0] if args else os.path.join(REPO, "build", "demo.png")
    if not QEMU and not os.access(SIM, os.X_OK):
        sys.exit("demo: %s is missing: run `make demo` (it builds it)" % SIM)
    proc, port = start_sim()
    try:
        with Bus("tcp://127.0.0.1:%d" % port, timeout=0.5) as bus:
            rec = Recorder(bus)
            if QEMU:
                say("The arm firmware (ID 1) runs on qemu-system-arm -M stm32vldiscovery, "
                    "its USART1 at tcp://127.0.0.1:%d." % port)
            else:
                say("servo-sim is running an arm (ID 1), a foot (ID 2) and a base (ID 3) "
                    "on a virtual RS485 bus at tcp://127.0.0.1:%d." % port)

            say("\n1. Scan: one broadcast PING, every servo answers in its own time slot.")
            found = bus.scan()
            want = sorted({ARM, FOOT, BASE})
            check([f.id for f in found] == want, "the scan did not find IDs %s" % want)
            for f in found:
                v = bus.variant(f.id)
                say("   found ID %d: %s, model 0x%04X, %s" % (
                    f.id, v.name if v else "?", bus.read(f.id, "model_number"),
                    "healthy" if f.err == 0 else "ERR 0x%02X" % f.err))

            say("\n2. The arm will not move before it knows where zero is:")
            try:
                bus.move(ARM, 90, speed=90)
                check(False, "the arm accepted a move before homing")
            except Exception as e:  # the SDK raises a clear error
                say("   move refused: %s" % str(e).split(" — ")[0])
            say("   Homing: back off switch 1 if needed, seek it (zero), reverse to switch 2 "
                "(the end).")
            bus.home(ARM)
            rec.wait(30, [ARM], until=lambda: bus.homing_status(ARM).state in (2, 3))
            st = bus.homing_status(ARM)
            check(st.state == 2 and bus.read(ARM, "ccw_angle_limit") == 420,
                  "homing did not find the 420 degree travel")
            say("   homing %s: limits %d..%d degrees (the travel between the switches)" % (
                st.text, bus.read(ARM, "cw_angle_limit"), bus.read(ARM, "ccw_angle_limit")))

            say("\n3. A trapezoidal move: to 90 degrees at 180 deg/s, ramps of 360 deg/s^2.")
            bus.write(ARM, {"acceleration": 36, "deceleration": 36})
            t = time.monotonic()
            bus.move(ARM, 90, speed=180)
            rec.wait(8, [ARM], until=lambda: bus.read(ARM, "moving") == 0)
            check(bus.position(ARM) == 90, "the arm did not arrive at 90")
            say("   arrived at %d degrees after %.2f s (ideal trapezoid: %.2f s)" % (
                bus.position(ARM), time.monotonic() - t, 330 / 180 + 180 / 360))

            say("\n4. A trajectory: 150, 200, 250 (passed through without stopping), then "
                "back to 120.")
            bus.trajectory_write(ARM, [(150, 120), (200, 180), (250, 120), (120, 150)])
            bus.trajectory_action(ARM)
            rec.wait(1.0, [ARM])
            rec.wait(8, [ARM], until=lambda: bus.read(ARM, "moving") == 0)
            check(bus.position(ARM) == 120, "the trajectory did not end at 120")
            say("   done at %d degrees" % bus.position(ARM))

            if QEMU:
                say("\n5. Speed mode (the base's, here on the arm: both limits 0): 120 deg/s "
                    "forward.")
                bus.write(ARM, {"cw_angle_limit": 0, "ccw_angle_limit": 0})
            else:
                say("\n5. Speed mode on the base: 120 deg/s forward.")
            bus.set_speed(BASE, 120)
            rec.wait(1.5, [ARM, BASE])
            speed = bus.read(BASE, "present_speed")
            check(abs(speed - 120) <= 10, "the %s is not turning at 120 deg/s" % BASE_NAME)
            say("   %s turning at %d deg/s" % (BASE_NAME, speed))

            say("\n6. Heartbeat: the host goes quiet for 1.5 s (a crashed controller) ...")
            time.sleep(1.5)
            speed = bus.read(BASE, "present_speed")
            check(abs(speed) <= 5, "the heartbeat did not stop the %s" % BASE_NAME)
            say("   ... the %s stopped by itself after 500 ms without a packet: speed now "
                "%d deg/s" % (BASE_NAME, speed))
            rec.wait(0.5, [ARM, BASE])

            if QEMU:
                say("\n7. Rule 3: speed 0 stops whatever runs. The arm (limits 0..420 "
                    "again): a long move, then speed 0.")
                bus.write(ARM, {"cw_angle_limit": 0, "ccw_angle_limit": 420})
                bus.move(FOOT, 60, speed=60)
            else:
                say("\n7. Rule 3: speed 0 stops whatever runs. Foot: a long move, then "
                    "speed 0.")
                bus.move(FOOT, 300, speed=60)
            rec.wait(1.0, [FOOT])
            bus.stop(FOOT)
            rec.wait(1.0, [FOOT])
            check(bus.read(FOOT, "moving") == 0, "speed 0 did not stop the %s" % FOOT_NAME)
            say("   %s stopped near %d degrees (torque off, coasting to rest)" % (
                FOOT_NAME, bus.position(FOOT)))
            plot(rec, out_png)
    finally:
        if QEMU:
            proc.stop()
        else:
            proc.terminate()
            proc.wait(timeout=10)
    if PROBLEMS:
        sys.exit("demo: %d step(s) did not do what they should: %s" % (
            len(PROBLEMS), "; ".join(PROBLEMS)))
    say("\nAll steps did what they should.")


if __name__ == "__main__":
    main()
