"""servoctl's command line: argument types and the parser."""

import argparse
import math

from .. import protocol as P
from ..registers import BAUD_RATES
from . import config, discover, firmware, ids, monitor, moving, table
from .common import PROG


def int_id(text):
    try:
        value = int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError("'%s' is not an ID (0-253)" % text) from None
    if not 0 <= value <= P.ID_MAX:
        raise argparse.ArgumentTypeError("ID %d is out of range 0-253" % value)
    return value


def baud_rate(text):
    try:
        value = int(text)
    except ValueError:
        value = None
    if value not in BAUD_RATES:
        raise argparse.ArgumentTypeError("baud %s is not one of %s" % (
            text, ", ".join(map(str, BAUD_RATES))))
    return value


def number(kind, lo, hi, what):
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


SECONDS = number(float, 0.01, 60.0, "seconds")
WAIT_SECONDS = number(float, 0.1, 3600.0, "seconds")


class Parser(argparse.ArgumentParser):
    """Usage errors in one line on stderr, exit status 2."""

    def error(self, message):
        self.exit(2, "%s: %s (see `%s --help`)\n" % (
            PROG, " ".join(str(message).split()), self.prog))


def _bus_options():
    """The bus options, accepted before or after the command."""
    common = Parser(add_help=False)
    g = common.add_argument_group("bus options (before or after the command)")
    g.add_argument("--port", default=argparse.SUPPRESS,
                   help="tcp://HOST:PORT (servo-sim) or a serial device such as "
                        "/dev/ttyUSB0 (default: $SERVOBUS_PORT)")
    g.add_argument("--baud", type=baud_rate, default=argparse.SUPPRESS,
                   help="host baud rate (default 9600; the base's default is 115200)")
    g.add_argument("--id", type=int_id, default=argparse.SUPPRESS,
                   help="servo ID (default 1)")
    g.add_argument("--timeout", type=SECONDS, default=argparse.SUPPRESS,
                   help="seconds to wait for an answer, 0.01-60 (default: from the baud "
                        "rate)")
    return common


def _wait_options(sp, default):
    sp.add_argument("--wait-timeout", dest="timeout_wait", type=WAIT_SECONDS,
                    default=default, help="seconds, 0.1-3600 (default %g)" % default)


def _table_commands(add):
    sp = add("scan", discover.cmd_scan,
             "find the servos on the bus (ID-slotted broadcast PING)")
    sp.add_argument("--all-bauds", action="store_true",
                    help="scan at every baud rate of the table (serial ports)")
    add("ping", discover.cmd_ping, "PING one servo")
    sp = add("get", table.cmd_get, "read registers")
    sp.add_argument("registers", nargs="+", metavar="REGISTER")
    sp.add_argument("--raw", action="store_true", help="print the bare values")
    sp = add("set", table.cmd_set,
             "write registers, all or nothing (every value checked first)")
    sp.add_argument("pairs", nargs="+", metavar="REGISTER VALUE")
    sp.add_argument("--force", action="store_true",
                    help="write it even if it locks servoctl out or the target ID answers")
    add("dump", table.cmd_dump, "read the whole control table, named, with units")


def _motion_commands(add):
    sp = add("move", moving.cmd_move, "position mode: write the goal (and speed)")
    sp.add_argument("position", help="goal in position units, or e.g. 90deg")
    sp.add_argument("--speed", help="moving speed in units/s, or e.g. 60deg/s")
    sp.add_argument("--wait", action="store_true", help="wait until the goal is reached")
    _wait_options(sp, 30.0)
    sp = add("speed", moving.cmd_speed,
             "speed mode: turn at SPEED (negative: other way; 0 stops)")
    sp.add_argument("speed", help="units/s, or e.g. -45deg/s")
    add("stop", moving.cmd_stop, "stop whatever the motor does (moving speed 0)")
    sp = add("home", moving.cmd_home, "start homing (register 24; arm, wrist, finger)")
    sp.add_argument("--wait", action="store_true", help="wait until homing is done")
    _wait_options(sp, 60.0)
    sp = add("traj", moving.cmd_traj, "write a trajectory and run it")
    sp.add_argument("points", nargs="+", metavar="ANGLE:SPEED")
    sp.add_argument("--no-run", action="store_true", help="store it only")
    sp.add_argument("--wait", action="store_true", help="wait until it has run")
    _wait_options(sp, 60.0)
    sp.add_argument("--point-size", type=int, choices=(3, 4), default=None)


def _servo_commands(add):
    sp = add("set-id", discover.cmd_set_id, "give the servo a new ID (refused if one is taken)")
    sp.add_argument("new_id", type=int_id, metavar="NEW_ID")
    sp.add_argument("--force", action="store_true", help="even if a servo answers at NEW_ID")
    sp = add("monitor", monitor.cmd_monitor,
             "print position, speed, temperature and errors live")
    sp.add_argument("--interval", type=number(float, 0.0, 3600.0, "seconds"), default=0.1,
                    help="seconds between samples, 0-3600 (default 0.1)")
    sp.add_argument("--duration", type=number(float, 0.01, 86400.0, "seconds"),
                    help="stop after this many seconds")
    sp.add_argument("--count", type=number(int, 1, 10 ** 9, "samples"),
                    help="stop after this many samples")
    sp.add_argument("--plot", metavar="FILE.png", help="write a plot of position and speed")
    sp = add("update", firmware.cmd_update, "send a firmware image over the bus "
             "(PROTOCOL.md §10); the servo restarts into it")
    sp.add_argument("file", metavar="FILE", help="the stamped image (tools/fwstamp.py)")
    sp.add_argument("--no-check", action="store_true",
                    help="send the file as it is: no image or model check on the host")
    sp.add_argument("--retries", type=number(int, 0, 100, "retries"), default=5,
                    help="times a frame is sent again after NAK or silence, 0-100 "
                         "(default 5)")
    sp.set_defaults(prepare=firmware.prepare_update)
    sp = add("config", config.cmd_config, "save a servo's settings to a JSON file, "
             "restore them onto a servo of the same variant, or diff servos and files")
    sp.add_argument("action", choices=("save", "restore", "diff"))
    sp.add_argument("sources", nargs="+", metavar="FILE|ID",
                    help="save/restore: FILE; diff: one or two of FILE or ID (id:N), "
                         "one of them compared with --id")
    sp.add_argument("--with-id", action="store_true", help="restore: the file's ID too")
    sp.add_argument("--with-baud", action="store_true", help="restore: its baud too")
    sp.add_argument("--dry-run", action="store_true", help="restore: say, write nothing")
    sp.add_argument("--force", action="store_true",
                    help="restore: even settings that lock servoctl out, or a taken ID")
    sp = add("reset", discover.cmd_reset, "factory reset (ID becomes 1)")
    sp.add_argument("--yes", action="store_true", help="really do it")
    sp.add_argument("--force", action="store_true", help="even if a servo answers at ID 1")


def build_parser():
    """servoctl's parser: the bus options, then one sub-command per job."""
    common = _bus_options()
    p = Parser(
        prog=PROG, parents=[common],
        description="Talk to D5 5D smart bus servos on a serial port or on servo-sim.",
        epilog="Registers are named as in docs/registers.md (or given by address); values "
               "are in the register's unit, or physical with a unit: 90deg, 45deg/s, 8ms.")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    sub.required = True

    def add(name, func, help_text):
        sp = sub.add_parser(name, parents=[common], help=help_text, description=help_text)
        sp.set_defaults(func=func)
        return sp

    _table_commands(add)
    _motion_commands(add)
    _servo_commands(add)
    ids.add_commands(add)
    from ..studio import add_command  # servoctl studio: the browser app (docs/studio.md)
    add_command(add)
    return p
