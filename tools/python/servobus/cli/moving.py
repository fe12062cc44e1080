"""servoctl's motion commands: move, speed, stop, home, traj."""

import time

from ..errors import RangeError, ServoBusError
from ..registers import REGISTERS
from .common import UsageError, heartbeat_note, show, wait_still


def cmd_move(bus, args):
    goal = REGISTERS["goal_position"]
    speed_reg = REGISTERS["moving_speed"]
    resolution = bus.resolution(args.id)
    position = goal.parse(args.position, resolution)
    speed = None
    if args.speed is not None:
        speed = speed_reg.parse(args.speed, resolution)
        if speed == 0:
            raise UsageError("--speed 0 does not move: speed 0 stops the motor (rule 3); "
                              "give a speed, e.g. --speed 60deg/s")
    elif bus.read(args.id, speed_reg) == 0:
        raise UsageError("ID %d's moving speed is 0 (as after power-up or a stop), so a "
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
    heartbeat_note(bus, args.id)
    return 0


def cmd_speed(bus, args):
    reg = REGISTERS["moving_speed"]
    resolution = bus.resolution(args.id)
    speed = reg.parse(args.speed, resolution)
    variant = bus.variant(args.id)
    if speed and not (variant and variant.name == "base"):
        limits = bus.read_many(args.id, ["cw_angle_limit", "ccw_angle_limit"])
        if limits["cw_angle_limit"] or limits["ccw_angle_limit"]:
            raise UsageError(
                "ID %d is in position mode (angle limits %d..%d): a speed there is only "
                "the speed of the next move; for speed mode first run `servoctl --id %d "
                "set cw_angle_limit 0 ccw_angle_limit 0`" % (
                    args.id, limits["cw_angle_limit"], limits["ccw_angle_limit"], args.id))
    bus.set_speed(args.id, speed)
    print("ID %d: %s" % (args.id, show(reg, speed, resolution)))
    if speed:
        heartbeat_note(bus, args.id)
    return 0


def cmd_stop(bus, args):
    bus.stop(args.id)
    print("ID %d: moving_speed = 0 (stop)" % args.id)
    return 0


def cmd_home(bus, args):
    variant = bus.variant(args.id)
    if variant and not variant.photo_switches:
        raise UsageError("ID %d is a %s: no photo switches, so no homing (§9); its "
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
            wait_still(bus, args.id, args.timeout_wait)
            reg = bus.position_register(args.id)
            print("ID %d: trajectory done at %s" % (
                args.id, reg.format(bus.read(args.id, reg), bus.resolution(args.id))))
        else:
            heartbeat_note(bus, args.id)
    return 0
