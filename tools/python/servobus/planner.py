"""The firmware's motion planner on the host (issue 29: Servo Studio's trajectory editor
overlays the planned profile on the measured response).

The same integer rules as src/planner.c (a one-tick trapezoidal planner in counts x 2^24
at 1 kHz, braking along the exact discrete curve), src/scale.c (speeds and ramps from
register units), and src/sequence.c (a trajectory runs through its points without
stopping while the direction holds, each point's speed from that point on; it stops at
a point where the direction changes). A plan is what the reference does; the measured
shaft follows it within the position loop's error."""

import math

from . import values as V

SHIFT = 24
ONE = 1 << SHIFT
TICKS_PER_S = 1000          # SCALE_TICKS_PER_S
MAX_SPEED_DPS = 1080        # SCALE_MAX_SPEED_DPS
COUNTS_PER_REV = 16384      # every board of board/<name>/board.c
INT32_MAX = (1 << 31) - 1


def dps_q24(cpr, dps):
    return (dps * cpr << SHIFT) // (360 * TICKS_PER_S)


def speed_q24(units_per_s, resolution, cpr=COUNTS_PER_REV):
    """scale_speed_q24: units/s to counts/tick x 2^24, capped at 1080 deg/s; at least 1."""
    v = (units_per_s * resolution * cpr << SHIFT) // (3600 * TICKS_PER_S)
    return max(1, min(v, dps_q24(cpr, MAX_SPEED_DPS)))


def accel_q24(reg, vmax, cpr=COUNTS_PER_REV):
    """scale_accel_q24: a ramp register (x10 deg/s^2; 0 = no ramp) to counts/tick^2 x 2^24."""
    if reg == 0:
        return vmax if vmax > 0 else 1
    return max(1, (reg * 10 * cpr << SHIFT) // (360 * TICKS_PER_S * TICKS_PER_S))


def _div_round(num, den):
    """div_round of src/scale.c: half away from zero."""
    q = (abs(num) + den // 2) // den
    return q if num >= 0 else -q


def _brake_loss(dec, n):
    return dec * n * (n + 1) // 2


def brake_speed(dist, dec):
    """planner_brake_speed: the highest speed that still stops within dist."""
    if dist <= 0:
        return 0
    n = (math.isqrt(8 * (dist // dec) + 1) - 1) // 2
    while _brake_loss(dec, n + 1) <= dist:
        n += 1
    while n and _brake_loss(dec, n) > dist:
        n -= 1
    return min((dist + _brake_loss(dec, n)) // (n + 1), INT32_MAX)


def _ramp(vel, want, acc, dec):
    if vel == want:
        return want
    up = want > vel if vel > 0 else (want < vel if vel < 0 else True)
    if vel > 0 and want < 0:
        return max(0, vel - dec)
    if vel < 0 and want > 0:
        return min(0, vel + dec)
    step = acc if up else dec
    if want > vel:
        return vel + step if want - vel > step else want
    return vel - step if vel - want > step else want


def step_to(pos, vel, target, vmax, acc, dec):
    """planner_step_to: one tick; (pos, vel, at rest on the target)."""
    err = target - pos
    if err == 0 and vel == 0:
        return pos, vel, True
    speed = min(brake_speed(abs(err), dec), vmax)
    vel = _ramp(vel, -speed if err < 0 else speed, acc, dec)
    pos += vel
    return pos, vel, pos == target and vel == 0


def _run_end(points, i, start):
    prev, direction, j = start, 0, i
    while j < len(points):
        p = points[j][0]
        d = (p > prev) - (p < prev)
        if direction and d and d != direction:
            break
        if d:
            direction = d
        prev = p
        j += 1
    return j - 1


def trajectory(start, points, resolution=10, acc=0, dec=0, cpr=COUNTS_PER_REV,
               every_s=0.01, limit_s=120.0):
    """The planned reference of a trajectory: [(t seconds, position units)] every
    every_s, from start (position units) through points [(angle units, speed units/s)]
    with the ramp registers acc, dec (x10 deg/s^2; 0 = no ramp), until it rests on the
    last point (at most limit_s)."""
    V.strict_integer(start, "start")
    V.strict_integer(resolution, "resolution", 1, 255)
    if not points:
        return [(0.0, start)]

    def q24(units):  # scale_units_to_counts (counts rounded), then x 2^24
        return _div_round(units * resolution * cpr, 3600) * ONE

    def units(p):  # scale_counts_to_units
        return _div_round((p >> SHIFT) * 3600, resolution * cpr)

    pts = [(q24(a), s) for a, s in points]
    pos, vel = q24(start), 0
    nxt, stop = 0, _run_end(pts, 0, pos)
    target = pts[stop][0]

    def limits(speed):
        vmax = speed_q24(speed, resolution, cpr)
        return vmax, accel_q24(acc, vmax, cpr), accel_q24(dec, vmax, cpr)
    vmax, a, d = limits(pts[0][1])
    out, every = [(0.0, start)], max(1, round(every_s * TICKS_PER_S))
    for tick in range(1, int(limit_s * TICKS_PER_S) + 1):
        pos, vel, rest = step_to(pos, vel, target, vmax, a, d)
        if tick % every == 0:
            out.append((tick / TICKS_PER_S, units(pos)))
        pt = pts[nxt][0]
        passed = pos >= pt if vel > 0 else pos <= pt if vel < 0 else rest
        if passed and nxt < stop:
            nxt += 1
            vmax, a, d = limits(pts[nxt][1])
        elif rest:
            if stop + 1 >= len(pts):
                if tick % every:
                    out.append((tick / TICKS_PER_S, units(pos)))
                return out
            nxt = stop + 1
            stop = _run_end(pts, nxt, pos)
            target = pts[stop][0]
            vmax, a, d = limits(pts[nxt][1])
    return out
