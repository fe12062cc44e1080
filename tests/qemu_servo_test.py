#!/usr/bin/python3
"""qemu_servo_test.py - the arm firmware (the `qemu` build: the arm image with the plant
model and the RAM flash in place of motor and flash controller, hal/stm32f1/README.md)
on qemu-system-arm -M stm32vldiscovery, held through its USART1 socket to what the host
servo is held to. Every frame must be answered: nothing is sent twice, a lost frame
fails the test.

  bus:    PING, READ, WRITE (exact bytes), error answers (checksum, instruction), the
          return delay (8 ms factory, 0, 20 ms), status return levels 2/1/0, resync after
          garbage and after a frame with a lost byte, 200 frames back to back
  motion: homing to completion (travel 420 degrees, then holding at the end within the
          limits), a trapezoidal move to completion (time against the ideal printed), a
          trajectory, speed 0 stopping a move, the heartbeat stop, a latched protection
          (over-temperature) refusing motion until cleared

Usage: qemu_servo_test.py [group ...]  (groups: bus motion; default both) with the image
of `cmake --build --preset qemu` (build/qemu). The whole run is bounded (DEADLINE_S).
"""
import os
import sys
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "tools"))
sys.path.insert(0, os.path.join(REPO, "tools", "python"))

from qemu_servo import receive  # noqa: E402
from rawbus import connect, on_qemu, packet, reporter, status  # noqa: E402
from servobus import Bus  # noqa: E402
from servobus.errors import MotionRefused, StatusError  # noqa: E402

DEADLINE_S = 150.0
NAME = "qemu_servo_test"
ANSWER_S = 0.5  # longest wait for an answer: 8 ms delay + 7 bytes at 9600 + QEMU + TCP


fail, say = reporter(NAME)


def check(ok, msg):
    if not ok:
        fail(msg)


frame = packet  # an instruction packet (rawbus.py)


PING = frame(1, 0x01)
PING_OK = bytes.fromhex("D55D0103010005")
OK = status(1, 0)


class Wire:
    """Raw bytes on the emulated bus (the socket to USART1)."""

    def __init__(self, url):
        port = int(url.rsplit(":", 1)[1])
        self.sock = connect(port)
        self.frames = 0

    def close(self):
        self.sock.close()

    def collect(self, want, timeout):
        """Up to `want` bytes within timeout; (bytes, seconds to the first)."""
        try:
            return receive(self.sock, want, timeout)
        except ConnectionError as e:
            fail(str(e))

    def ask(self, pkt, answer, what, gap=None):
        """Send pkt (bytes of a list of chunks sent `gap` seconds apart); the exact
        answer must come, once. Returns seconds from the last byte sent to its first."""
        chunks = pkt if isinstance(pkt, list) else [pkt]
        for i, c in enumerate(chunks):
            if i and gap:
                time.sleep(gap)
            self.sock.sendall(c)
        self.frames += 1
        got, first = self.collect(len(answer), ANSWER_S)
        if got != answer:
            fail(f"{what}: sent {b''.join(chunks).hex(' ')}, expected {answer.hex(' ')}, "
                 f"got {got.hex(' ') or 'nothing (a lost frame)'}")
        extra, _ = self.collect(1, 0.03)
        check(not extra, f"{what}: more than one answer ({extra.hex(' ')} after it)")
        return first

    def silent(self, pkt, what, wait=0.1):
        """Send pkt; nothing may come back."""
        self.sock.sendall(pkt)
        got, _ = self.collect(1, wait)
        check(not got, f"{what}: expected no answer, got {got.hex(' ')}")


def read1(w, addr, value, what):
    w.ask(frame(1, 0x02, addr, 1), status(1, 0, value), what)


def bus_group(q):
    w = Wire(q.url)
    try:
        # PING and the return delay at factory (register 5 = 16 x 500 us).
        d = w.ask(PING, PING_OK, "PING")
        check(d >= 0.008 - 0.001, f"PING answered after {d * 1e3:.1f} ms, before the 8 ms "
              "return delay")
        say(f"PING -> {PING_OK.hex(' ')} after {d * 1e3:.1f} ms (return delay 8 ms)")
        w.ask(frame(1, 0x02, 0, 2), status(1, 0, 0x03, 0x52), "READ model number")
        w.ask(frame(1, 0x02, 3, 2), status(1, 0, 1, 0x00), "READ ID and baud (1, 9600)")
        # WRITE, then READ it back; the acceleration register is EEPROM (RAM flash).
        w.ask(frame(1, 0x03, 34, 0x30), OK, "WRITE acceleration 0x30")
        read1(w, 34, 0x30, "READ acceleration")
        say("PING, READ, WRITE: exact answers")

        # Errors: a checksum error is answered with ERR 0x10 and not executed; a READ past
        # the table and a WRITE of a read-only register with ERR 0x20.
        bad = bytearray(frame(1, 0x03, 34, 0x31))
        bad[-1] ^= 0xFF
        w.ask(bytes(bad), status(1, 0x10), "WRITE with a wrong checksum")
        read1(w, 34, 0x30, "READ acceleration after the bad WRITE (not executed)")
        w.ask(frame(1, 0x02, 48, 5), status(1, 0x20), "READ past the table")
        w.ask(frame(1, 0x03, 42, 1), status(1, 0x20), "WRITE of read-only register 42")
        w.ask(frame(1, 0x4E), status(1, 0x20), "unknown instruction 0x4E")
        # 0x7E with no parameter is an error answer's shape: silent (docs/decisions.md,
        # duplicate IDs); with a parameter it is an instruction error as §3.1 says
        w.silent(frame(1, 0x7E), "unknown instruction 0x7E (an error answer's shape)")
        w.ask(frame(1, 0x7E, 0x00), status(1, 0x20), "unknown instruction 0x7E with a parameter")
        w.silent(frame(2, 0x01), "PING to ID 2 (nobody)")
        say("errors: checksum ERR 0x10 (not executed), instruction ERR 0x20, other ID silent")

        # Return delay: 0, then 40 x 500 us, then back to the factory 16.
        w.ask(frame(1, 0x03, 5, 0), OK, "WRITE return delay 0")
        d0 = min(w.ask(PING, PING_OK, "PING at delay 0") for _ in range(5))
        w.ask(frame(1, 0x03, 5, 40), OK, "WRITE return delay 40")
        d20 = w.ask(PING, PING_OK, "PING at delay 20 ms")
        check(d20 >= 0.020 - 0.001, f"delay 20 ms: answered after {d20 * 1e3:.1f} ms")
        check(d20 - d0 >= 0.018, f"delay 20 ms answered only {1e3 * (d20 - d0):.1f} ms later "
              "than delay 0")
        w.ask(frame(1, 0x03, 5, 16), OK, "WRITE return delay 16")
        say(f"return delay: 0 -> {d0 * 1e3:.1f} ms, 40 (20 ms) -> {d20 * 1e3:.1f} ms "
            "(through QEMU and TCP)")

        # Status return levels (register 16): 2 all, 1 READ and PING, 0 PING only. A write
        # at a level that does not answer it is still executed.
        w.ask(frame(1, 0x03, 16, 1), OK, "WRITE level 1 (answered at the old level 2)")
        w.silent(frame(1, 0x03, 34, 0x31), "WRITE at level 1")
        read1(w, 34, 0x31, "READ at level 1 (the unanswered WRITE was executed)")
        w.ask(frame(1, 0x02, 48, 5), status(1, 0x20), "READ error at level 1")
        w.ask(PING, PING_OK, "PING at level 1")
        w.silent(frame(1, 0x03, 16, 0), "WRITE level 0 at level 1")
        w.silent(frame(1, 0x02, 34, 1), "READ at level 0")
        w.ask(PING, PING_OK, "PING at level 0")
        w.silent(frame(1, 0x03, 16, 2), "WRITE level 2 at level 0")
        read1(w, 16, 2, "READ level, back at 2")
        say("status return levels 2, 1, 0: answered exactly as §3.2 says")

        # Resync: garbage before a frame; a frame that lost a byte, a good one behind it.
        w.ask(bytes.fromhex("00FF13D5125D5DD5") + PING, PING_OK, "PING after garbage")
        w.ask(bytes.fromhex("5D5DD57FD5005D") + frame(1, 0x02, 3, 1), status(1, 0, 1),
              "READ ID after garbage")
        w.ask(bytes.fromhex("D55D030403000F") + PING, PING_OK,
              "PING behind a frame to ID 3 that lost a byte")
        # The broken WRITE's ERR 0x10 answer waits out the return delay; the PING arriving
        # meanwhile is executed and its answer replaces it (docs/decisions.md).
        w.ask(bytes.fromhex("D55D010403225A") + PING, PING_OK,
              "a WRITE that lost its data byte, then PING")
        read1(w, 34, 0x31, "READ acceleration (the broken WRITE was not executed)")
        # A frame cut by a pause longer than the 20.8 ms time-out is abandoned.
        cut = frame(1, 0x03, 34, 0x32)
        w.silent(cut[:5], "half a WRITE", wait=0.05)
        time.sleep(0.05)
        w.ask(cut[5:] + PING, PING_OK, "PING after the rest of the cut WRITE")
        read1(w, 34, 0x31, "READ acceleration (the cut WRITE was abandoned)")
        say("resync: garbage, a lost byte, an inter-byte time-out: one packet lost at most")

        # Back to back: every frame answered, none sent twice.
        t0 = time.monotonic()
        for i in range(100):
            w.ask(PING, PING_OK, f"PING {i} of 100 back to back")
            w.ask(frame(1, 0x02, 36, 2), status(1, 0, 0, 0), f"READ {i} of 100")
        say(f"200 frames back to back, every one answered ({time.monotonic() - t0:.1f} s)")
        w.ask(frame(1, 0x03, 34, 0), OK, "WRITE acceleration 0 (factory)")
    finally:
        w.close()
    return w.frames


def wait_for(bus, cond, timeout, period=0.05):
    """Poll cond() (each poll is bus traffic, so the heartbeat stays fed)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        v = cond()
        if v:
            return v
        time.sleep(period)
    return None


def motion_group(q):
    with Bus(q.url, timeout=ANSWER_S, raise_faults=False) as bus:
        # Homing: switch 1 at 0 degrees, switch 2 at 420; the shaft starts at 90.
        try:
            bus.move(1, 90, speed=90)
            fail("a move was accepted before homing")
        except MotionRefused:
            pass
        t0 = time.monotonic()
        bus.home(1)
        seen = []

        def homed():
            seen.append(bus.position(1))
            return bus.homing_status(1).state in (2, 3)
        check(wait_for(bus, homed, 30), "homing did not end within 30 s")
        st = bus.homing_status(1)
        lim = (bus.read(1, "cw_angle_limit"), bus.read(1, "ccw_angle_limit"))
        check(st.state == 2, f"homing {st.text}")
        check(lim == (0, 420), f"homing found limits {lim}, not 0..420 (the switches)")
        say(f"homing done in {time.monotonic() - t0:.1f} s: limits {lim[0]}..{lim[1]}")
        after = []
        wait_for(bus, lambda: after.append((bus.position(1), bus.read(1, "moving"))), 1.0)
        out = [p for p, _ in after if not 0 <= p <= 420]
        check(not out, f"after homing the arm left its limits 0..420: {out[:5]} "
              "(homing overshoot past the end switch)")
        check(after[-1] == (420, 0), f"not holding at the end 420 after homing: {after[-1]}")
        say("holding at the end (420) within the limits")

        # A trapezoidal move: 420 -> 90 at 180 deg/s, ramps 360 deg/s^2.
        bus.write(1, {"acceleration": 36, "deceleration": 36})
        t0 = time.monotonic()
        bus.move(1, 90, speed=180)
        check(wait_for(bus, lambda: bus.read(1, "moving") == 0, 8, 0.01), "the move never ended")
        took = time.monotonic() - t0
        ideal = 330 / 180 + 180 / 360
        check(bus.position(1) == 90, f"the move ended at {bus.position(1)}, not 90")
        # The planner counts control ticks; a host too loaded to run QEMU in real time
        # drops ticks (motion_poll) and stretches the move in wall time, never its end.
        check(took < 3 * ideal, f"the move took {took:.2f} s against an ideal {ideal:.2f} s")
        say(f"trapezoidal move 420 -> 90 at 180 deg/s: {took:.2f} s, ideal {ideal:.2f} s "
            "(+ a READ round trip of polling)")

        # A trajectory: through 150, 200, 250 without stopping, then back to 120.
        bus.trajectory_write(1, [(150, 120), (200, 180), (250, 120), (120, 150)])
        bus.trajectory_action(1)
        top = []

        def traj_done():
            top.append(bus.position(1))
            return len(top) > 5 and bus.read(1, "moving") == 0
        check(wait_for(bus, traj_done, 12), "the trajectory never ended")
        check(max(top) >= 245, f"the trajectory did not reach 250 first (top {max(top)})")
        check(bus.position(1) == 120, f"the trajectory ended at {bus.position(1)}, not 120")
        say(f"trajectory 150/200/250/120: turned at {max(top)}, ended at 120")

        # Speed 0 stops a move (rule 3): torque off, the arm coasts to rest.
        start = bus.position(1)
        bus.move(1, 400, speed=90)
        check(wait_for(bus, lambda: bus.position(1) >= start + 20, 2), "the move did not start")
        bus.stop(1)
        # Moving (42) stays 1 while the shaft still turns (issue 13): the arm coasts to
        # rest with the torque off, then reads moving 0.
        check(wait_for(bus, lambda: bus.read(1, "moving") == 0, 3),
              "speed 0: the arm never came to rest (moving stays 1)")
        wait_for(bus, lambda: False, 0.6)
        p1 = bus.position(1)
        wait_for(bus, lambda: False, 0.4)
        p2, v = bus.position(1), bus.read(1, "present_speed")
        check(p1 == p2 and v == 0, f"after speed 0 the arm did not come to rest "
              f"(position {p1} then {p2}, present speed {v})")
        check(start + 20 <= p2 < 380, f"speed 0 did not stop the move midway (at {p2})")
        say(f"speed 0 stopped the move at {p2} (target 400); present speed 0")

        # Heartbeat: a move, then 1.2 s without a packet; the servo stops after 500 ms.
        bus.write(1, {"moving_speed": 30})
        bus.move(1, 20, speed=30)
        wait_for(bus, lambda: False, 0.3)
        p0 = bus.position(1)
        time.sleep(1.2)
        p1, moving = bus.position(1), bus.read(1, "moving")
        time.sleep(0.2)
        p2 = bus.position(1)
        check(moving == 0 and p1 == p2, f"the heartbeat did not stop the arm (moving "
              f"{moving}, position {p1} then {p2})")
        travelled = p0 - p1
        check(10 <= travelled <= 30, f"heartbeat stop after {travelled} degrees at 30 deg/s "
              "(500 ms of motion is 15)")
        say(f"heartbeat: stopped on its own {travelled} degrees after the host went quiet")

        # A latched protection: over-temperature (limit 20 C < the board's 25 C) unloads
        # the motor and stays latched until cleared, once the condition is gone.
        bus.write(1, "temperature_limit", 20)
        check(wait_for(bus, lambda: bus.ping(1) & 0x01, 2.0), "no over-temperature within 2 s")
        try:
            bus.move(1, 200, speed=60)
            fail("a move was accepted while unloaded")
        except MotionRefused:
            pass
        try:
            bus.write(1, "clear_unload", 1)
            fail("clear_unload was accepted while the condition was present")
        except StatusError:
            pass
        bus.write(1, "temperature_limit", 80)
        wait_for(bus, lambda: False, 0.3)
        check(bus.ping(1) & 0x01, "the unload did not stay latched after the condition went")
        check(wait_for(bus, lambda: _try_clear(bus), 4.0), "clear_unload never accepted")
        check(bus.ping(1) == 0, "ERR not 0 after clear_unload")
        bus.move(1, 60, speed=120)
        check(wait_for(bus, lambda: bus.read(1, "moving") == 0 and bus.position(1) == 60, 5),
              "no move after the protection was cleared")
        say("protection: over-temperature latched, motion refused, cleared, moves again")


def _try_clear(bus):
    try:
        bus.write(1, "clear_unload", 1)
        return True
    except StatusError:
        return False


def main():
    groups = sys.argv[1:] or ["bus", "motion"]

    def run(q):
        say(" ".join(q.cmd))
        for g in groups:
            {"bus": bus_group, "motion": motion_group}[g](q)
            check(q.alive(), f"QEMU exited during {g}: the MCU reset or faulted")
    on_qemu(NAME, DEADLINE_S, run)


if __name__ == "__main__":
    main()
