"""servoctl: command line for the servo bus (python3 -m servobus, or the servoctl script).

Exit status: 0 done; 1 the bus or a servo said no, or a check on the bus failed (a
time-out, a refusal, two servos on one ID); 2 refused before anything was sent: bad
usage, a value out of range or not for the servo's variant, an unreadable or invalid
firmware image, or a setting that needs --force (or --yes). Every failure is one line on
stderr."""

import argparse
import math
import os
import re
import stat
import sys
import time

from . import image as I
from . import protocol as P
from .budget import CommitBudget
from .bus import Bus
from .errors import (BusTimeout, IdTaken, InstructionError, RangeError, ServoBusError,
                     UnknownRegister)
from .registers import BAUD_RATES, REGISTERS, VARIANTS, baud_of_code, register
from .update import IN_UPDATE_MODE as _IN_UPDATE_MODE

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


def _number(kind, lo, hi, what):
    """An argparse type: a finite int or float within lo..hi."""
    def parse(text):
        try:
            value = kind(text)
        except (ValueError, OverflowError):
            raise argparse.ArgumentTypeError("'%s' is not a number of %s" % (text, what)) \
                from None
        if not math.isfinite(value) or not lo <= value <= hi:
            raise argparse.ArgumentTypeError("%s: '%s' is out of range %g..%g" % (
                what, text, lo, hi))
        return value
    return parse


_SECONDS = _number(float, 0.01, 60.0, "seconds")
_WAIT_SECONDS = _number(float, 0.1, 3600.0, "seconds")


def _state_path():
    """Where servoctl keeps its flash commit estimate between runs (budget.py)."""
    if os.environ.get("SERVOBUS_STATE"):
        return os.environ["SERVOBUS_STATE"]
    base = os.environ.get("XDG_STATE_HOME") or os.path.join(
        os.path.expanduser("~"), ".local", "state")
    return os.path.join(base, "servobus", "commit-budget.json")


def _note(text):
    print("note: " + text, file=sys.stderr)


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
    found = bus.scan(all_bauds=args.all_bauds, check_duplicates=True)
    for note in bus.scan_notes:
        _note(note)
    bauds = "every baud" if args.all_bauds and not bus.is_tcp else "%d baud" % bus.baud
    if not found and bus.duplicates:
        raise ServoBusError("no servo answered a broadcast PING intact, and two servos "
                            "answer at ID %s: see \"Two servos on one ID\" in "
                            "tools/python/README.md" % ", ".join(map(str, bus.duplicates)))
    if not found:
        # Where cheap: one frame to the ID given (default 1) tells a servo in update mode.
        if not bus.scan_notes and bus.in_update_mode(args.id):
            raise ServoBusError("no servo answered a broadcast PING, but ID %d answers the "
                                "update handshake: %s — send a good image: `servoctl --id "
                                "%d update FILE`" % (args.id, _IN_UPDATE_MODE, args.id))
        raise ServoBusError("no servo answered a broadcast PING at %s%s" % (
            bauds, "" if args.all_bauds else " (try --all-bauds)"))
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
        if f.id in bus.duplicates:
            status = "TWO SERVOS ON THIS ID"
        print("%4d  %-7s  %7s  %s" % (f.id, name, "tcp" if bus.is_tcp else f.baud, status))
    if bus.duplicates:
        raise ServoBusError("two servos answer at ID %s: anything sent to that ID reaches "
                            "both; see \"Two servos on one ID\" in tools/python/README.md"
                            % ", ".join(map(str, bus.duplicates)))
    return 0


def cmd_ping(bus, args):
    try:
        err = bus.ping(args.id)
    except BusTimeout:
        if bus.in_update_mode(args.id):
            raise ServoBusError("ID %d does not answer PING but answers the update "
                                "handshake: %s — send a good image: `servoctl --id %d "
                                "update FILE`" % (args.id, _IN_UPDATE_MODE, args.id)) \
                from None
        raise
    if bus.duplicate(args.id):
        raise ServoBusError("two servos answer at ID %d (two answers to one PING, or "
                            "answers garbled by each other): see \"Two servos on one ID\" "
                            "in tools/python/README.md" % args.id)
    print("ID %d: present, %s" % (args.id, "no errors" if not err else
                                    "reports " + ", ".join(P.describe_err(err))))
    return 0


def _variant_for(bus, servo_id, regs):
    """The servo's variant if any of regs is not on every variant (else None: no READ)."""
    if all(set(r.variants) == set(VARIANTS) for r in regs):
        return None
    return bus.variant(servo_id)


def cmd_get(bus, args):
    regs = [register(r) for r in args.registers]
    variant = _variant_for(bus, args.id, regs)
    for r in regs:
        if not r.readable:
            raise RangeError("%s (register %d) is write-only: it reads 0 whatever was "
                             "written" % (r.name, r.address))
        if not r.applies_to(variant):
            raise RangeError("%s (register %d) does not exist on the %s (it is for %s)" % (
                r.name, r.address, variant.name, ", ".join(r.variants)))
    resolution = None
    if not args.raw and any(r.unit in ("position", "speed", "dir_speed") for r in regs):
        resolution = bus.resolution(args.id)
    for r in regs:
        value = bus.read(args.id, r)
        print(value if args.raw else _show(r, value, resolution or 10))
    return 0


def _new_baud(bus, servo_id, code):
    """The baud a register 4 code gives this servo (code 0: its variant's default)."""
    try:
        variant = bus.variant(servo_id)
    except ServoBusError:
        variant = None
    return baud_of_code(code, variant)


def _lockout_checks(bus, args, values):
    """Settings after which servoctl could no longer reach the servo as it is called
    now: refused without --force (usage error), with the way back in the message."""
    sid = args.id
    if values.get("status_return_level") == 0:
        raise _UsageError(
            "status_return_level 0: ID %d would answer nothing but PING, so get, dump and "
            "monitor time out and writes go unconfirmed (servoctl still reaches it: `set "
            "status_return_level 2` brings it back); add --force to write it" % sid)
    if "temperature_limit" in values:
        now = bus.read(sid, "present_temperature")
        if values["temperature_limit"] <= now:
            raise _UsageError(
                "temperature_limit %d C: ID %d is at %d C now, so it would unload at once "
                "(over-temperature: torque off, motion refused) until the limit is raised "
                "and `set clear_unload 1` written; add --force to write it" % (
                    values["temperature_limit"], sid, now))
    if "baud_rate" in values:
        baud = _new_baud(bus, sid, values["baud_rate"])
        if baud != bus.baud:
            raise _UsageError(
                "baud_rate %d: ID %d would then answer at %d baud only, and servoctl talks "
                "at %d: every later command needs --baud %d; add --force to write it" % (
                    values["baud_rate"], sid, baud, bus.baud, baud))


def cmd_set(bus, args):
    if len(args.pairs) % 2:
        raise RangeError("set takes REGISTER VALUE pairs; '%s' has no value" % args.pairs[-1])
    pairs = [(register(args.pairs[i]), args.pairs[i + 1]) for i in range(0, len(args.pairs), 2)]
    resolution = None
    if any(r.unit in ("position", "speed", "dir_speed") for r, _ in pairs):
        resolution = bus.resolution(args.id)
    values = {}
    for r, text in pairs:  # every value checked before anything is sent
        if r.name in values:
            raise RangeError("%s is given twice" % r.name)
        values[r.name] = r.parse(text, resolution or 10)
    bus.plan_write(args.id, values)  # range, variant, CW <= CCW: before anything is sent
    if not args.force:
        _lockout_checks(bus, args, values)
    new_id = values.get("id", args.id)
    if new_id != args.id:
        if bus.duplicate(args.id):
            raise ServoBusError("two servos answer at ID %d: a new ID would go to both "
                                "(see \"Two servos on one ID\" in tools/python/README.md)"
                                % args.id)
        if not args.force:
            try:
                bus.refuse_taken(new_id)
            except IdTaken as e:
                raise IdTaken("%s (or add --force)" % e) from None
    _write_clearing(bus, args.id, values)
    wait, confirmed = bus.commit_wait, bus.confirmed
    for name, value in values.items():
        r = REGISTERS[name]
        text = _show(r, value, resolution or 10)
        if name == "goal_position" and confirmed:
            held = bus.read(new_id, r)
            if held != value:
                text += " (the servo holds %s: clamped to its angle limits)" % r.format(
                    held, resolution or 10)
        print("%s: written%s" % (text, "" if confirmed else " (not confirmed: at status "
                                 "return level %d ID %d does not answer writes)" % (
                                     bus.known_level(new_id), new_id)))
    if new_id != args.id:
        print("ID %d is now ID %d" % (args.id, new_id))
    if "baud_rate" in values:
        baud = _new_baud(bus, new_id, values["baud_rate"])
        if baud != bus.baud:
            _note("ID %d now answers at %d baud: add --baud %d to later commands" % (
                new_id, baud, baud))
    _commit_note(new_id, [wait] if wait else [])
    return 0


def _write_clearing(bus, servo_id, values):
    """write_many(); a clear_unload refused while the fault bit is still live is tried
    again for a while: the servo needs about 0.5 s to see a cause gone (a temperature
    limit just raised, src/safety.c)."""
    deadline = time.monotonic() + 2.0
    while True:
        try:
            return bus.write_many(servo_id, values)
        except InstructionError as e:
            if "clear_unload" not in values or not e.err & P.ERR_FAULTS or \
                    time.monotonic() > deadline:
                if "clear_unload" in values and e.err & P.ERR_FAULTS:
                    raise InstructionError(
                        servo_id, e.err, e.what, "the cause (%s) is still there: clear "
                        "the unload once it has gone" % ", ".join(
                            P.describe_err(e.err & P.ERR_FAULTS))) from None
                raise
            time.sleep(0.1)


def _commit_note(servo_id, waits):
    """Issue 19: the value is in force, but a commit past the servo's flash budget
    reaches flash later; say how long the power must stay on."""
    if not waits:
        return
    wait = max(waits)
    _note("ID %d has used its burst of quick flash commits (estimate from this host's "
          "writes: 64 at once, then one per 64 s): the new value is in force now but "
          "reaches flash in up to %.0f s — do not cut the power before %s" % (
              servo_id, math.ceil(wait), time.strftime("%H:%M:%S",
                                                       time.localtime(time.time() + wait))))


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
    speed_reg = REGISTERS["moving_speed"]
    resolution = bus.resolution(args.id)
    position = goal.parse(args.position, resolution)
    speed = None
    if args.speed is not None:
        speed = speed_reg.parse(args.speed, resolution)
        if speed == 0:
            raise _UsageError("--speed 0 does not move: speed 0 stops the motor (rule 3); "
                              "give a speed, e.g. --speed 60deg/s")
    elif bus.read(args.id, speed_reg) == 0:
        raise _UsageError("ID %d's moving speed is 0 (as after power-up or a stop), so a "
                          "goal alone does not move it: give --speed, e.g. --speed 60deg/s"
                          % args.id)
    bus.move(args.id, position, speed)
    held = bus.read(args.id, goal)
    variant = bus.variant(args.id)
    clamped = ""
    if held != position and not (variant and variant.name == "base"):
        clamped = " (asked %s: clamped to the angle limits)" % goal.format(position,
                                                                           resolution)
    print("ID %d: goal %s%s%s" % (args.id, goal.format(held, resolution), clamped,
                                  "" if speed is None else ", speed " +
                                  speed_reg.format(speed, resolution)))
    if args.wait:
        reg = bus.position_register(args.id)
        deadline = time.monotonic() + args.timeout_wait
        while True:
            state = bus.read_many(args.id, [reg, "moving"])
            if not state["moving"] and abs(state[reg.name] - held) <= 1:
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
    variant = bus.variant(args.id)
    if speed and not (variant and variant.name == "base"):
        limits = bus.read_many(args.id, ["cw_angle_limit", "ccw_angle_limit"])
        if limits["cw_angle_limit"] or limits["ccw_angle_limit"]:
            raise _UsageError(
                "ID %d is in position mode (angle limits %d..%d): a speed there is only "
                "the speed of the next move; for speed mode first run `servoctl --id %d "
                "set cw_angle_limit 0 ccw_angle_limit 0`" % (
                    args.id, limits["cw_angle_limit"], limits["ccw_angle_limit"], args.id))
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
    variant = bus.variant(args.id)
    if variant and not variant.photo_switches:
        raise _UsageError("ID %d is a %s: no photo switches, so no homing (§9); its "
                          "position counts from where it started" % (args.id, variant.name))
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
    try:
        bus.set_id(args.id, args.new_id, check_free=not args.force)
    except IdTaken as e:
        raise IdTaken("%s (or add --force)" % e) from None
    print("ID %d is now ID %d%s" % (args.id, args.new_id, "" if bus.confirmed else
                                    " (it answers PING there)"))
    _commit_note(args.new_id, [bus.commit_wait] if bus.commit_wait else [])
    return 0


def cmd_reset(bus, args):
    if not args.yes:
        raise _UsageError("reset restores every register of ID %d to its factory value "
                          "(ID 1, default baud); add --yes to do it" % args.id)
    try:
        bus.reset(args.id, check_free=not args.force)
    except IdTaken as e:
        raise IdTaken("reset would move ID %d to ID 1: %s (or add --force)" % (
            args.id, e)) from None
    print("ID %d: reset to factory values; it now answers at ID 1 and its default baud" %
          args.id)
    _commit_note(1, [bus.commit_wait] if bus.commit_wait else [])
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
    """Before the bus is opened: read the image (a regular file, at most one byte more
    than the largest image) and (unless --no-check) validate it."""
    try:
        st = os.stat(args.file)
        if not stat.S_ISREG(st.st_mode):
            raise _UsageError("%s is not a regular file (a device, FIFO or directory): "
                              "give the image file" % args.file)
        if st.st_size > I.MAX_BYTES + 1:
            raise _UsageError("%s has %d bytes: larger than any image (%d bytes at most)"
                              % (args.file, st.st_size, I.MAX_BYTES))
        with open(args.file, "rb") as f:
            args.data = f.read(I.MAX_BYTES + 1)
    except OSError as e:
        raise _UsageError("cannot read %s: %s" % (args.file, e.strerror or e)) from None
    if not args.data:
        raise _UsageError("%s is empty (0 bytes): not an image" % args.file)
    args.info = None if args.no_check else I.validate(args.data)


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
    if version is None:
        print("ID %d: updated in %.1f s; it answers PING (its firmware version cannot be "
              "read: status return level 0)" % (args.id, time.monotonic() - t0))
    else:
        print("ID %d: updated in %.1f s, now runs firmware version %d" % (
            args.id, time.monotonic() - t0, version))
    return 0


class _UsageError(Exception):
    """Bad usage found by a command (exit status 2)."""


# ---- argument parsing ---------------------------------------------------------------

class _Parser(argparse.ArgumentParser):
    """Usage errors in one line on stderr, exit status 2."""

    def error(self, message):
        self.exit(2, "%s: %s (see `%s --help`)\n" % (
            PROG, " ".join(str(message).split()), self.prog))


def _parser():
    common = _Parser(add_help=False)
    g = common.add_argument_group("bus options (before or after the command)")
    g.add_argument("--port", default=argparse.SUPPRESS,
                   help="tcp://HOST:PORT (servo-sim) or a serial device such as "
                        "/dev/ttyUSB0 (default: $SERVOBUS_PORT)")
    g.add_argument("--baud", type=_baud, default=argparse.SUPPRESS,
                   help="host baud rate (default 9600; the base's default is 115200)")
    g.add_argument("--id", type=_int_id, default=argparse.SUPPRESS,
                   help="servo ID (default 1)")
    g.add_argument("--timeout", type=_SECONDS, default=argparse.SUPPRESS,
                   help="seconds to wait for an answer, 0.01-60 (default: from the baud "
                        "rate)")

    p = _Parser(
        prog=PROG, parents=[common],
        description="Talk to D5 5D smart bus servos on a serial port or on servo-sim.",
        epilog="Registers are named as in docs/registers.md (or given by address); values "
               "are in the register's unit, or physical with a unit: 90deg, 45deg/s, 8ms.")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    def add(name, func, help_text):
        sp = sub.add_parser(name, parents=[common], help=help_text, description=help_text)
        sp.set_defaults(func=func)
        return sp

    def wait_options(sp, default):
        sp.add_argument("--wait-timeout", dest="timeout_wait", type=_WAIT_SECONDS,
                        default=default, help="seconds, 0.1-3600 (default %g)" % default)

    force = "write it even if it locks servoctl out or the target ID answers"
    sp = add("scan", cmd_scan, "find the servos on the bus (ID-slotted broadcast PING)")
    sp.add_argument("--all-bauds", action="store_true",
                    help="scan at every baud rate of the table (serial ports)")
    add("ping", cmd_ping, "PING one servo")
    sp = add("get", cmd_get, "read registers")
    sp.add_argument("registers", nargs="+", metavar="REGISTER")
    sp.add_argument("--raw", action="store_true", help="print the bare values")
    sp = add("set", cmd_set, "write registers, all or nothing (every value checked first)")
    sp.add_argument("pairs", nargs="+", metavar="REGISTER VALUE")
    sp.add_argument("--force", action="store_true", help=force)
    add("dump", cmd_dump, "read the whole control table, named, with units")
    sp = add("move", cmd_move, "position mode: write the goal (and speed)")
    sp.add_argument("position", help="goal in position units, or e.g. 90deg")
    sp.add_argument("--speed", help="moving speed in units/s, or e.g. 60deg/s")
    sp.add_argument("--wait", action="store_true", help="wait until the goal is reached")
    wait_options(sp, 30.0)
    sp = add("speed", cmd_speed, "speed mode: turn at SPEED (negative: other way; 0 stops)")
    sp.add_argument("speed", help="units/s, or e.g. -45deg/s")
    add("stop", cmd_stop, "stop whatever the motor does (moving speed 0)")
    sp = add("home", cmd_home, "start homing (register 24; arm, wrist, finger)")
    sp.add_argument("--wait", action="store_true", help="wait until homing is done")
    wait_options(sp, 60.0)
    sp = add("traj", cmd_traj, "write a trajectory and run it")
    sp.add_argument("points", nargs="+", metavar="ANGLE:SPEED")
    sp.add_argument("--no-run", action="store_true", help="store it only")
    sp.add_argument("--wait", action="store_true", help="wait until it has run")
    wait_options(sp, 60.0)
    sp.add_argument("--point-size", type=int, choices=(3, 4), default=None)
    sp = add("set-id", cmd_set_id, "give the servo a new ID (refused if one is taken)")
    sp.add_argument("new_id", type=_int_id, metavar="NEW_ID")
    sp.add_argument("--force", action="store_true", help="even if a servo answers at NEW_ID")
    sp = add("monitor", cmd_monitor, "print position, speed, temperature and errors live")
    sp.add_argument("--interval", type=_number(float, 0.0, 3600.0, "seconds"), default=0.1,
                    help="seconds between samples, 0-3600 (default 0.1)")
    sp.add_argument("--duration", type=_number(float, 0.01, 86400.0, "seconds"),
                    help="stop after this many seconds")
    sp.add_argument("--count", type=_number(int, 1, 10 ** 9, "samples"),
                    help="stop after this many samples")
    sp.add_argument("--plot", metavar="FILE.png", help="write a plot of position and speed")
    sp = add("update", cmd_update, "send a firmware image over the bus (PROTOCOL.md §10); "
             "the servo restarts into it")
    sp.add_argument("file", metavar="FILE", help="the stamped image (tools/fwstamp.py)")
    sp.add_argument("--no-check", action="store_true",
                    help="send the file as it is: no image or model check on the host")
    sp.add_argument("--retries", type=_number(int, 0, 100, "retries"), default=5,
                    help="times a frame is sent again after NAK or silence, 0-100 "
                         "(default 5)")
    sp.set_defaults(prepare=prepare_update)
    sp = add("reset", cmd_reset, "factory reset (ID becomes 1)")
    sp.add_argument("--yes", action="store_true", help="really do it")
    sp.add_argument("--force", action="store_true", help="even if a servo answers at ID 1")
    from .studio import add_command  # servoctl studio: the browser app (docs/studio.md)
    add_command(add)
    return p


_MOVING = ("move", "speed", "traj", "home")


def _interrupted(bus, args):
    """The one line Ctrl-C leaves: what is still going on, and how to stop it."""
    step = getattr(bus, "update_step", None) if bus is not None else None
    sid = getattr(args, "id", 1)
    if step in ("end of batch", "restart"):
        return ("interrupted after the image was sent: ID %d is checking and installing "
                "it; PING it in a few seconds (`servoctl --id %d ping`)" % (sid, sid))
    if step is not None:
        return ("interrupted during the update (at the %s): ID %d's update session ends "
                "10 s after the last frame, and until then it refuses every command but "
                "PING and READ; it keeps its firmware (a servo in update mode stays "
                "there): run the update again" % (step, sid))
    if getattr(args, "command", None) in _MOVING:
        return ("interrupted: ID %d may still be moving — `servoctl --id %d stop` stops "
                "it (with the heartbeat on, register 17, it stops by itself 500 ms after "
                "the last packet)" % (sid, sid))
    return "interrupted"


def _fault_note(bus, args):
    """Live fault bits seen in answers: the command went through, but say so (a latched
    protection unload refuses motion until cleared)."""
    if args.command in ("ping", "scan", "monitor") or not bus.faults:
        return
    for servo_id in sorted(bus.faults):
        try:
            err = bus.ping(servo_id) & P.ERR_FAULTS  # live now, after the command?
        except ServoBusError:
            continue
        if not err:
            continue
        _note("ID %d reports %s: a protection unload stays latched (torque off, motion "
              "refused) until the cause is gone and `servoctl --id %d set clear_unload 1`"
              % (servo_id, ", ".join(P.describe_err(err & P.ERR_FAULTS)), servo_id))


def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    # A negative value (-100, -45deg/s) is a value, not an option: a leading space keeps
    # argparse from taking it for one, and the value parsers ignore it.
    argv = [" " + a if re.match(r"-\.?\d", a) else a for a in argv]
    try:
        args = _parser().parse_args(argv)
    except SystemExit as e:
        return e.code if isinstance(e.code, int) else 2
    port = getattr(args, "port", None) or os.environ.get("SERVOBUS_PORT")
    args.id = getattr(args, "id", 1)
    args.force = getattr(args, "force", False)
    if not port:
        print("%s: no bus given: use --port tcp://HOST:PORT (servo-sim) or --port "
              "/dev/ttyUSB0, or set SERVOBUS_PORT" % PROG, file=sys.stderr)
        return 2
    bus = None
    try:
        if getattr(args, "prepare", None):
            args.prepare(args)
        with Bus(port, baud=getattr(args, "baud", 9600), timeout=getattr(args, "timeout", None),
                 raise_faults=False) as bus:
            bus.commit_budget = CommitBudget(_state_path())
            rc = args.func(bus, args)
            _fault_note(bus, args)
            return rc
    except (_UsageError, RangeError, UnknownRegister, IdTaken, I.ImageError) as e:
        return _fail(e, 2)  # refused before anything was sent
    except ServoBusError as e:
        return _fail(e, 1)
    except KeyboardInterrupt:
        print("%s: %s" % (PROG, _interrupted(bus, args)), file=sys.stderr)
        return 130
    except OSError as e:  # a serial adapter unplugged mid-command, a full disk for --plot
        return _fail("%s: %s" % (getattr(e, "filename", None) or port, e.strerror or e), 1)


def _fail(e, status):
    print("%s: %s" % (PROG, " ".join(str(e).split())), file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main())
