"""servoctl: command line for the servo bus (python3 -m servobus, or the servoctl script).

Exit status: 0 done, 1 the bus or a servo said no (message on stderr), 2 bad usage (also
an unreadable or invalid firmware image for `update`)."""

import argparse
import os
import re
import sys
import time

from . import image as I
from . import protocol as P
from .bus import Bus
from .errors import RangeError, ServoBusError
from .registers import BAUD_RATES, REGISTERS, register

PROG = "servoctl"


def _int_id(text):
    try:
        value = int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError("'%s' is not an ID (0-253)" % text) from None
    if not 0 <= value <= P.ID_MAX:
        raise argparse.ArgumentTypeError("ID %d is out of range 0-253" % value)
    return value


def _baud(text):
    try:
        value = int(text)
    except ValueError:
        value = None
    if value not in BAUD_RATES:
        raise argparse.ArgumentTypeError("baud %s is not one of %s" % (
            text, ", ".join(map(str, BAUD_RATES))))
    return value


def _show(reg, value, resolution):
    return "%s = %s" % (reg.name, "-" if value is None else reg.format(value, resolution))


def _heartbeat_note(bus, servo_id):
    """Motion started by a one-shot command stops 500 ms after the last packet when the
    heartbeat (register 17, on by factory default) is enabled: say so."""
    try:
        on = bus.read(servo_id, "heartbeat_enable")
    except ServoBusError:
        return
    if on:
        print("note: heartbeat on (register 17): ID %d stops 500 ms after the last packet; "
              "use --wait or `monitor` to keep talking, or `set heartbeat_enable 0`" %
              servo_id, file=sys.stderr)


def _wait_still(bus, servo_id, timeout):
    """Poll until the servo reports moving 0 (the polling keeps the heartbeat alive)."""
    deadline = time.monotonic() + timeout
    while bus.read(servo_id, "moving"):
        if time.monotonic() > deadline:
            raise ServoBusError("ID %d still moving after %.0f s" % (servo_id, timeout))
        time.sleep(0.05)


# ---- commands -----------------------------------------------------------------------

def cmd_scan(bus, args):
    found = bus.scan(all_bauds=args.all_bauds)
    for note in bus.scan_notes:
        print("note: " + note, file=sys.stderr)
    bauds = "every baud" if args.all_bauds and not bus.is_tcp else "%d baud" % bus.baud
    if not found:
        print("no servo answered a broadcast PING at %s%s" % (
            bauds, "" if args.all_bauds else " (try --all-bauds)"))
        return 1
    print("%d servo%s found at %s:" % (len(found), "" if len(found) == 1 else "s", bauds))
    print("%4s  %-7s  %7s  %s" % ("ID", "variant", "baud", "status"))
    for f in found:
        if f.baud != bus.baud:
            bus.set_baud(f.baud)
        try:
            v = bus.variant(f.id)
            name = v.name if v else "?"
        except ServoBusError:
            name = "?"
        status = "ok" if not f.err else ", ".join(P.describe_err(f.err))
        print("%4d  %-7s  %7s  %s" % (f.id, name, "tcp" if bus.is_tcp else f.baud, status))
    return 0


def cmd_ping(bus, args):
    err = bus.ping(args.id)
    print("ID %d: present, %s" % (args.id, "no errors" if not err else
                                    "reports " + ", ".join(P.describe_err(err))))
    return 0


def cmd_get(bus, args):
    regs = [register(r) for r in args.registers]
    resolution = None
    if not args.raw and any(r.unit in ("position", "speed", "dir_speed") for r in regs):
        resolution = bus.resolution(args.id)
    for r in regs:
        value = bus.read(args.id, r)
        print(value if args.raw else _show(r, value, resolution or 10))
    return 0


def cmd_set(bus, args):
    if len(args.pairs) % 2:
        raise RangeError("set takes REGISTER VALUE pairs; '%s' has no value" % args.pairs[-1])
    pairs = [(register(args.pairs[i]), args.pairs[i + 1]) for i in range(0, len(args.pairs), 2)]
    resolution = None
    if any(r.unit in ("position", "speed", "dir_speed") for r, _ in pairs):
        resolution = bus.resolution(args.id)
    values = [(r, r.parse(text, resolution or 10)) for r, text in pairs]  # all checked first
    for r, value in values:
        bus.write(args.id, r, value)
        print("%s: written" % _show(r, value, resolution or 10))
    return 0


def cmd_dump(bus, args):
    variant = bus.variant(args.id)
    rows = bus.dump(args.id)
    values = {r.name: v for r, v in rows}
    resolution = values.get("angle_resolution") or 10
    print("ID %d: %s (model 0x%04X), firmware %s" % (
        args.id, variant.name if variant else "unknown variant", values["model_number"],
        values["firmware_version"]))
    print("%5s  %-22s  %-26s  %-6s  %s" % ("addr", "name", "value", "access", "area"))
    for r, v in rows:
        addr = "%d-%d" % (r.address, r.address + 1) if r.size == 2 else str(r.address)
        if v is None:
            text = "(write-only)" if r.applies_to(variant) else "(not on this variant)"
        else:
            text = r.format(v, resolution)
        print("%5s  %-22s  %-26s  %-6s  %s" % (addr, r.name, text, r.access, r.area))
    return 0


def cmd_move(bus, args):
    goal = REGISTERS["goal_position"]
    resolution = bus.resolution(args.id)
    position = goal.parse(args.position, resolution)
    speed = None
    if args.speed is not None:
        speed = REGISTERS["moving_speed"].parse(args.speed, resolution)
    bus.move(args.id, position, speed)
    print("ID %d: goal %s%s" % (args.id, goal.format(position, resolution),
                                "" if speed is None else ", speed " +
                                REGISTERS["moving_speed"].format(speed, resolution)))
    if args.wait:
        reg = bus.position_register(args.id)
        goal_now = bus.read(args.id, "goal_position")  # clamped to the limits
        deadline = time.monotonic() + args.timeout_wait
        while True:
            state = bus.read_many(args.id, [reg, "moving"])
            if not state["moving"] and abs(state[reg.name] - goal_now) <= 1:
                print("ID %d: reached %s" % (args.id, reg.format(state[reg.name], resolution)))
                return 0
            if time.monotonic() > deadline:
                raise ServoBusError("ID %d did not reach the goal within %.0f s (position %d, "
                                    "moving %d)" % (args.id, args.timeout_wait, state[reg.name],
                                                    state["moving"]))
            time.sleep(0.05)
    _heartbeat_note(bus, args.id)
    return 0


def cmd_speed(bus, args):
    reg = REGISTERS["moving_speed"]
    resolution = bus.resolution(args.id)
    speed = reg.parse(args.speed, resolution)
    bus.set_speed(args.id, speed)
    print("ID %d: %s" % (args.id, _show(reg, speed, resolution)))
    if speed:
        _heartbeat_note(bus, args.id)
    return 0


def cmd_stop(bus, args):
    bus.stop(args.id)
    print("ID %d: moving_speed = 0 (stop)" % args.id)
    return 0


def cmd_home(bus, args):
    bus.home(args.id)
    print("ID %d: homing started" % args.id)
    if args.wait:
        bus.wait_homed(args.id, timeout=args.timeout_wait)
        limits = bus.read_many(args.id, ["cw_angle_limit", "ccw_angle_limit"])
        print("ID %d: homing done, travel 0..%d" % (args.id, limits["ccw_angle_limit"]))
    return 0


def cmd_traj(bus, args):
    points = []
    for text in args.points:
        angle, sep, speed = text.partition(":")
        try:
            points.append((int(angle, 0), int(speed, 0)))
        except ValueError:
            raise RangeError("trajectory point '%s': expected ANGLE:SPEED in position units, "
                             "e.g. 90:60" % text) from None
    bus.trajectory_write(args.id, points, args.point_size)
    print("ID %d: %d trajectory points stored" % (args.id, len(points)))
    if not args.no_run:
        bus.trajectory_action(args.id)
        print("ID %d: trajectory started" % args.id)
        if args.wait:
            _wait_still(bus, args.id, args.timeout_wait)
            reg = bus.position_register(args.id)
            print("ID %d: trajectory done at %s" % (
                args.id, reg.format(bus.read(args.id, reg), bus.resolution(args.id))))
        else:
            _heartbeat_note(bus, args.id)
    return 0


def cmd_set_id(bus, args):
    bus.set_id(args.id, args.new_id)
    print("ID %d is now ID %d" % (args.id, args.new_id))
    return 0


def cmd_reset(bus, args):
    if not args.yes:
        raise RangeError("reset restores every register of ID %d to its factory value (ID 1, "
                         "default baud); add --yes to do it" % args.id)
    bus.reset(args.id)
    print("ID %d: reset to factory values; it now answers at ID 1 and its default baud" %
          args.id)
    return 0


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


class _Progress:
    """A progress bar on stderr: blocks sent / total and bytes."""

    WIDTH = 30

    def __init__(self, stream=sys.stderr):
        self.stream = stream
        self.tty = stream.isatty()
        self.start = time.monotonic()
        self.open = False  # a line without its newline on the terminal

    def close(self):
        if self.open:
            self.stream.write("\n")
            self.open = False

    def __call__(self, done, total, nbytes, total_bytes):
        filled = self.WIDTH * done // total if total else self.WIDTH
        line = "[%s%s] %2d/%d blocks, %6d/%d bytes, %4.1f s" % (
            "#" * filled, "." * (self.WIDTH - filled), done, total, nbytes, total_bytes,
            time.monotonic() - self.start)
        if self.tty:
            self.stream.write("\r" + line)
            self.open = True
            if done == total:
                self.close()
        elif done == 0 or done == total or done % 4 == 0:
            self.stream.write(line + "\n")  # a log: not every block
        self.stream.flush()


def prepare_update(args):
    """Before the bus is opened: read the image and (unless --no-check) validate it."""
    try:
        with open(args.file, "rb") as f:
            args.data = f.read()
    except OSError as e:
        raise _UsageError("cannot read %s: %s" % (args.file, e.strerror or e)) from None
    args.info = None if args.no_check else I.validate(args.data)
    if args.retries < 0:
        raise _UsageError("--retries is 0 or more")


def cmd_update(bus, args):
    if args.info is not None:
        print("%s: %s" % (args.file, args.info.describe()), file=sys.stderr)
        try:
            if bus.present(args.id):
                print("ID %d runs firmware version %d" % (
                    args.id, bus.read(args.id, "firmware_version")), file=sys.stderr)
        except ServoBusError:
            pass
    t0 = time.monotonic()
    bar = _Progress()
    try:
        version = bus.update(args.id, args.data, progress=bar, retries=args.retries,
                             check=not args.no_check,
                             notify=lambda text: print("%s: note: %s" % (PROG, text),
                                                       file=sys.stderr))
    finally:
        bar.close()
    print("ID %d: updated in %.1f s, now runs firmware version %d" % (
        args.id, time.monotonic() - t0, version))
    return 0


class _UsageError(Exception):
    """Bad usage found by a command (exit status 2)."""


# ---- argument parsing ---------------------------------------------------------------

def _parser():
    common = argparse.ArgumentParser(add_help=False)
    g = common.add_argument_group("bus options (before or after the command)")
    g.add_argument("--port", default=argparse.SUPPRESS,
                   help="tcp://HOST:PORT (servo-sim) or a serial device such as "
                        "/dev/ttyUSB0 (default: $SERVOBUS_PORT)")
    g.add_argument("--baud", type=_baud, default=argparse.SUPPRESS,
                   help="host baud rate (default 9600; the base's default is 115200)")
    g.add_argument("--id", type=_int_id, default=argparse.SUPPRESS,
                   help="servo ID (default 1)")
    g.add_argument("--timeout", type=float, default=argparse.SUPPRESS,
                   help="seconds to wait for an answer (default: from the baud rate)")

    p = argparse.ArgumentParser(
        prog=PROG, parents=[common],
        description="Talk to D5 5D smart bus servos on a serial port or on servo-sim.",
        epilog="Registers are named as in docs/registers.md (or given by address); values "
               "are in the register's unit, or physical with a unit: 90deg, 45deg/s, 8ms.")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    def add(name, func, help_text):
        sp = sub.add_parser(name, parents=[common], help=help_text, description=help_text)
        sp.set_defaults(func=func)
        return sp

    sp = add("scan", cmd_scan, "find the servos on the bus (ID-slotted broadcast PING)")
    sp.add_argument("--all-bauds", action="store_true",
                    help="scan at every baud rate of the table (serial ports)")
    add("ping", cmd_ping, "PING one servo")
    sp = add("get", cmd_get, "read registers")
    sp.add_argument("registers", nargs="+", metavar="REGISTER")
    sp.add_argument("--raw", action="store_true", help="print the bare values")
    sp = add("set", cmd_set, "write registers (range-checked before sending)")
    sp.add_argument("pairs", nargs="+", metavar="REGISTER VALUE")
    add("dump", cmd_dump, "read the whole control table, named, with units")
    sp = add("move", cmd_move, "position mode: write the goal (and speed)")
    sp.add_argument("position", help="goal in position units, or e.g. 90deg")
    sp.add_argument("--speed", help="moving speed in units/s, or e.g. 60deg/s")
    sp.add_argument("--wait", action="store_true", help="wait until the goal is reached")
    sp.add_argument("--wait-timeout", dest="timeout_wait", type=float, default=30.0)
    sp = add("speed", cmd_speed, "speed mode: turn at SPEED (negative: other way; 0 stops)")
    sp.add_argument("speed", help="units/s, or e.g. -45deg/s")
    add("stop", cmd_stop, "stop whatever the motor does (moving speed 0)")
    sp = add("home", cmd_home, "start homing (register 24)")
    sp.add_argument("--wait", action="store_true", help="wait until homing is done")
    sp.add_argument("--wait-timeout", dest="timeout_wait", type=float, default=60.0)
    sp = add("traj", cmd_traj, "write a trajectory and run it")
    sp.add_argument("points", nargs="+", metavar="ANGLE:SPEED")
    sp.add_argument("--no-run", action="store_true", help="store it only")
    sp.add_argument("--wait", action="store_true", help="wait until it has run")
    sp.add_argument("--wait-timeout", dest="timeout_wait", type=float, default=60.0)
    sp.add_argument("--point-size", type=int, choices=(3, 4), default=None)
    sp = add("set-id", cmd_set_id, "give the servo a new ID (refused if one is taken)")
    sp.add_argument("new_id", type=_int_id, metavar="NEW_ID")
    sp = add("monitor", cmd_monitor, "print position, speed, temperature and errors live")
    sp.add_argument("--interval", type=float, default=0.1, help="seconds between samples")
    sp.add_argument("--duration", type=float, help="stop after this many seconds")
    sp.add_argument("--count", type=int, help="stop after this many samples")
    sp.add_argument("--plot", metavar="FILE.png", help="write a plot of position and speed")
    sp = add("update", cmd_update, "send a firmware image over the bus (PROTOCOL.md §10); "
             "the servo restarts into it")
    sp.add_argument("file", metavar="FILE", help="the stamped image (tools/fwstamp.py)")
    sp.add_argument("--no-check", action="store_true",
                    help="send the file as it is: no image or model check on the host")
    sp.add_argument("--retries", type=int, default=5,
                    help="times a frame is sent again after NAK or silence (default 5)")
    sp.set_defaults(prepare=prepare_update)
    sp = add("reset", cmd_reset, "factory reset (ID becomes 1)")
    sp.add_argument("--yes", action="store_true", help="really do it")
    from .studio import add_command  # servoctl studio: the browser app (docs/studio.md)
    add_command(add)
    return p


def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    # A negative value (-100, -45deg/s) is a value, not an option: a leading space keeps
    # argparse from taking it for one, and the value parsers ignore it.
    argv = [" " + a if re.match(r"-\.?\d", a) else a for a in argv]
    args = _parser().parse_args(argv)
    port = getattr(args, "port", None) or os.environ.get("SERVOBUS_PORT")
    args.id = getattr(args, "id", 1)
    if not port:
        print("%s: no bus given: use --port tcp://HOST:PORT (servo-sim) or --port "
              "/dev/ttyUSB0, or set SERVOBUS_PORT" % PROG, file=sys.stderr)
        return 2
    try:
        if getattr(args, "prepare", None):
            args.prepare(args)
        with Bus(port, baud=getattr(args, "baud", 9600),
                 timeout=getattr(args, "timeout", None)) as bus:
            return args.func(bus, args)
    except (I.ImageError, _UsageError) as e:
        print("%s: %s" % (PROG, e), file=sys.stderr)
        return 2
    except ServoBusError as e:
        print("%s: %s" % (PROG, e), file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
