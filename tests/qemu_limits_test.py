#!/usr/bin/python3
"""qemu_limits_test.py - issue 25 on the real arm image under QEMU (the `qemu` build, as
qemu_servo_test.py runs it): the angle limits hold whatever runs when they change.

  narrowed mid-move: homed, moving down from 420 toward 20, CW limit 300 written on the
      way: the arm rests at 300 (it rested at 20); written when the arm is already past
      it (CW 200 at about 150): it brakes with its deceleration and comes back to 200
  speed mode left while turning: both limits 0, turning down at 120 deg/s, then CW 0 /
      CCW 200 written: it stops with its deceleration within [0, 200] and holds there (it
      kept turning, past its own end switch)

The host keeps talking (READs every 20 ms), so the heartbeat never stops anything here.
"""
import os
import sys
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "tools"))

from qemu_servo import receive  # noqa: E402
from rawbus import connect, on_qemu, packet, reporter  # noqa: E402

DEADLINE_S = 120.0
NAME = "qemu_limits_test"


fail, say = reporter(NAME)


frame = packet  # an instruction packet (rawbus.py)


class Arm:
    """The arm at ID 1 over the raw socket to USART1: every packet answered."""

    def __init__(self, url):
        port = int(url.rsplit(":", 1)[1])
        self.sock = connect(port)

    def ask(self, ins, *params):
        self.sock.sendall(frame(1, ins, *params))
        ans, _ = receive(self.sock, 4, 0.5)  # may bring more than 4: recv takes what came
        if len(ans) < 4:
            fail(f"no answer to instruction {ins:#x} {params}")
        if len(ans) < 4 + ans[3]:
            ans += receive(self.sock, 4 + ans[3] - len(ans), 0.5)[0]
        if len(ans) != 4 + ans[3]:
            fail(f"instruction {ins:#x} {params}: answer {ans.hex(' ')}")
        if ans[4] & 0x20:
            fail(f"instruction {ins:#x} {params} refused (ERR {ans[4]:#x})")
        return ans[5:-1]

    def write(self, addr, *data):
        self.ask(0x03, addr, *data)

    def write16(self, addr, *values):
        self.write(addr, *[b for v in values for b in (v & 0xFF, v >> 8)])

    def state(self):
        """(position, moving, CW, CCW, goal) as READs return them."""
        t = self.ask(0x02, 0, 50)
        u16 = lambda a: t[a] | t[a + 1] << 8  # noqa: E731
        pos = u16(40) - (0x10000 if u16(40) & 0x8000 else 0)
        return pos, t[42], u16(6), u16(8), u16(30)

    def watch(self, seconds, until=None):
        """Read every 20 ms for up to seconds (or until until(state)); the states read."""
        seen = []
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            seen.append(self.state())
            if until and until(seen[-1]):
                break
            time.sleep(0.02)
        return seen

    def rests(self, seconds=8.0):
        """Wait for moving 0 at one position for 0.3 s; the states read on the way."""
        seen = self.watch(seconds, lambda s: s[1] == 0)
        if seen[-1][1]:
            fail(f"still moving after {seconds} s: {seen[-1]}")
        later = self.watch(0.3)
        if later[-1][0] != seen[-1][0] or later[-1][1]:
            fail(f"moving 0 at {seen[-1][0]}, then {later[-1]}")
        return seen + later


def narrowed_mid_move(arm):
    arm.write16(6, 0, 420)  # the measured travel again
    arm.write(34, 36, 36)
    arm.write16(32, 60)
    arm.write16(30, 20)  # down toward 20
    seen = arm.watch(6, lambda s: s[0] <= 350)
    if seen[-1][0] > 350:
        fail(f"the move down did not start: {seen[-1]}")
    arm.write16(6, 300)  # CW limit 300 while the arm passes 350
    seen = arm.rests()
    pos, _, cw, ccw, goal = seen[-1]
    low = min(s[0] for s in seen)
    if (pos, cw, goal) != (300, 300, 300) or low < 299:
        fail(f"CW 300 written mid-move: rests at {pos} (lowest {low}), CW {cw}, goal {goal}")
    say(f"CW 300 written at about 350 on the way to 20: rests at {pos}, goal reads {goal}")

    arm.write16(6, 0)
    arm.write16(30, 20)
    seen = arm.watch(8, lambda s: s[0] <= 150)
    if seen[-1][0] > 150:
        fail(f"the second move down did not pass 150: {seen[-1]}")
    arm.write16(6, 200)  # the arm is already past it
    seen = arm.rests()
    pos, _, cw, _, goal = seen[-1]
    low = min(s[0] for s in seen)
    if (pos, goal) != (200, 200) or low >= 150:
        fail(f"CW 200 written at about 150: rests at {pos} (lowest {low}), goal {goal}")
    say(f"CW 200 written past it at about 150: braked to {low}, came back to {pos}")


def speed_mode_left(arm):
    arm.write16(6, 0, 0)  # speed mode
    arm.write16(32, 0x8000 | 120)  # down at 120 deg/s
    seen = arm.watch(4, lambda s: s[0] <= 120)
    if seen[-1][0] > 120 or not seen[-1][1]:
        fail(f"speed mode did not turn the arm down: {seen[-1]}")
    arm.write16(6, 0, 200)  # position mode again while it turns
    seen = arm.rests()
    pos, _, cw, ccw, goal = seen[-1]
    low = min(s[0] for s in seen)
    if not (0 <= pos <= 200) or goal != pos or low < 0:
        fail(f"limits 0..200 written while turning: rests at {pos} (lowest {low}), goal {goal}")
    later = arm.watch(1.0)
    if any(s[0] != pos or s[1] for s in later):
        fail(f"after the stop at {pos} it moved on: {later[-1]}")
    say(f"speed mode left at about 120 deg/s: stopped at {pos} within 0..200, holds")


def run(q):
    arm = Arm(q.url)
    arm.write(24, 1)  # homing: switch 1 at 0, switch 2 at 420
    seen = arm.watch(40, lambda s: False if s[1] else arm.ask(0x02, 24, 1)[0] >> 4 != 1)
    status = arm.ask(0x02, 24, 1)[0] >> 4
    if status != 2:
        fail(f"homing ended in status {status}")
    say(f"homed: limits {seen[-1][2]}..{seen[-1][3]}")
    narrowed_mid_move(arm)
    speed_mode_left(arm)


def main():
    on_qemu(NAME, DEADLINE_S, run)


if __name__ == "__main__":
    main()
