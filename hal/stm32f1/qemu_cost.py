#!/usr/bin/python3
"""qemu_cost.py - on-target figures of the arm firmware (the `qemu` build: the arm image
with the plant model and RAM flash), in Cortex-M3 instructions counted by single-stepping
it under QEMU through QEMU's gdb stub (`make bench`):

  per received byte   the USART1 interrupt of each byte of a READ frame: handler,
                      servo_rx_isr, hal_clock_us, frame_rx_byte, exception return; and
                      the receiver's worst cases: a frame full of D5 5D pairs (each a
                      candidate), and the same with a bad checksum, whose last byte
                      hands over to one of them
  reply latency       at return delay 0: from the interrupt of the frame's last byte,
                      through the main loop's passes that dispatch the READ and start the
                      answer, to the transmit step (tx_step) that writes its first
                      byte (a control tick that falls due on the way counted too,
                      its plant model not); in instructions, in us at 72 MHz (1.5 cycles
                      per instruction: two flash wait states), and the functions that
                      take most
  per control tick    motion_poll when a tick runs: at rest, homing, moving, holding; the
                      plant model's integration (plant_advance, QEMU build only) left out
  per re-plan         command_written for a new goal during a move, and the tick after it

QEMU's stub steps with interrupts and timers held (its default); an interrupt still
tail-chains at an exception return (the next byte's, counted as that byte's; a pending
SysTick's, left out). Under QEMU the main loop sleeps in WFI between
passes (main.c); the latency count runs over the sleep (continues to the instruction
after WFI) and leaves it out, where silicon's loop would spin one more pass.

Needs only qemu-system-arm and python3 (it speaks gdb's remote protocol itself).
Exit status 1 past a budget: 100 instructions per received byte on average, 3,600 per
control tick (5 % of a 72 MHz core at 1 kHz).
Usage: qemu_cost.py [build/qemu/servo-qemu.elf]   (boots servo-qemu-full.bin beside it)
"""
import bisect
import os
import socket
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(REPO, "tools"))

from qemu_servo import QemuServo, free_port  # noqa: E402

OK = bytes.fromhex("D55D01020003")
CYCLES_PER_INSTRUCTION = 1.5
MHZ = 72


def frame(*b):
    body = [b[0], len(b)] + list(b[1:])
    return bytes([0xD5, 0x5D] + body + [sum(body) & 0xFF])


class Image:
    """Function address ranges of the ELF, and the address of its WFI."""

    def __init__(self, elf):
        self.funcs, self.addr = {}, {}
        out = subprocess.run(["arm-none-eabi-nm", "-S", "--defined-only", elf], check=True,
                             capture_output=True, text=True).stdout
        for line in out.splitlines():
            p = line.split()
            if len(p) == 4 and p[2] in "tTW":
                a = int(p[0], 16) & ~1
                # Under -flto GCC may specialise a function into a clone (foo.constprop.0)
                # and drop the original: the clone answers to foo.
                name = p[3].split(".")[0]
                self.funcs[a] = (name, int(p[1], 16))
                if name not in self.addr or name == p[3]:
                    self.addr[name] = a
        self.starts = sorted(self.funcs)
        dis = subprocess.run(["arm-none-eabi-objdump", "-d", elf], check=True,
                             capture_output=True, text=True).stdout
        wfi = [line for line in dis.splitlines() if line.rstrip().endswith("\twfi")]
        if len(wfi) != 1:
            raise RuntimeError("expected one WFI in the image (main.c), found %d" % len(wfi))
        self.wfi = int(wfi[0].split(":")[0], 16)

    def owner(self, pc):
        i = bisect.bisect_right(self.starts, pc) - 1
        if i >= 0 and pc < self.starts[i] + self.funcs[self.starts[i]][1]:
            return self.funcs[self.starts[i]][0]
        return "?"


class Stub:
    """QEMU's gdb stub, spoken directly (no acks): breakpoints, continue, step, registers,
    memory."""

    def __init__(self, port):
        t0 = time.monotonic()
        while True:
            try:
                self.s = socket.create_connection(("127.0.0.1", port), timeout=60)
                break
            except OSError:
                if time.monotonic() - t0 > 10:
                    raise
                time.sleep(0.05)
        self.s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.buf = b""
        self._send("QStartNoAckMode")
        self._reply()
        self.buf = self.buf.replace(b"+", b"")

    def _send(self, data):
        d = data.encode()
        self.s.sendall(b"$" + d + b"#%02x" % (sum(d) & 0xFF))

    def _reply(self):
        while True:
            i = self.buf.find(b"$")
            j = self.buf.find(b"#", i + 1) if i >= 0 else -1
            if i >= 0 and j >= 0 and len(self.buf) >= j + 3:
                data = self.buf[i + 1:j]
                self.buf = self.buf[j + 3:]
                return data.decode()
            chunk = self.s.recv(65536)
            if not chunk:
                raise RuntimeError("QEMU's gdb stub closed")
            self.buf += chunk

    def cmd(self, data):
        self._send(data)
        return self._reply()

    def regs(self):
        """(pc, sp, lr, ipsr): IPSR 0 is thread mode."""
        g = self.cmd("g")
        word = lambda i: int.from_bytes(bytes.fromhex(g[8 * i:8 * i + 8]), "little")  # noqa
        xpsr = int.from_bytes(bytes.fromhex(g[-8:]), "little")
        return word(15) & ~1, word(13), word(14), xpsr & 0x1FF

    def step(self):
        self.cmd("s")
        return self.regs()

    def mem32(self, addr):
        return int.from_bytes(bytes.fromhex(self.cmd("m%x,4" % addr)), "little")

    def bp(self, addr, on=True):
        r = self.cmd("%s0,%x,2" % ("Z" if on else "z", addr))
        assert r == "OK", r

    def cont(self):
        """Run to the next breakpoint; its registers."""
        r = self.cmd("c")
        assert r.startswith(("T05", "S05")), r
        return self.regs()

    def run_for(self, seconds):
        """Run freely for a while (the firmware's clock runs), then stop."""
        self._send("c")
        time.sleep(seconds)
        self.s.sendall(b"\x03")
        self._reply()

    def run_to(self, addr):
        self.bp(addr)
        r = self.cont()
        self.bp(addr, False)
        return r


class Cost:
    def __init__(self, elf):
        self.img = Image(elf)
        self.gport = free_port()
        # -icount: the firmware's clock follows the instructions run (16 ns each, near
        # silicon's 21 ns), not the host's clock, which runs on while the stub steps:
        # stepping a frame took milliseconds of it, past the 2 ms idle-line time-out,
        # so heads dropped mid-frame at random under load and the figures varied from
        # run to run (a receive interrupt of 1,838 instructions seen once). Idle in WFI,
        # it runs in real time (sleep=on), so run_for() and the homing wait still hold.
        self.q = QemuServo(elf[:-len(".elf")] + "-full.bin", elf,
                           extra=("-gdb", f"tcp:127.0.0.1:{self.gport}", "-S",
                                  "-icount", "shift=4,sleep=on"))
        self.stub = Stub(self.gport)
        self.ser = socket.create_connection(("127.0.0.1", self.q.port))
        self.ser.setblocking(False)

    def close(self):
        self.ser.close()
        self.stub.s.close()
        self.q.stop()

    def drain(self):
        got = b""
        while True:
            try:
                chunk = self.ser.recv(4096)
            except BlockingIOError:
                return got
            if not chunk:
                return got
            got += chunk

    def ask(self, pkt, seconds=0.15):
        self.drain()
        self.ser.sendall(pkt)
        self.stub.run_for(seconds)
        return self.drain()

    def count(self, stop, skip=(), per=None):
        """Step until stop(pc, sp, ipsr); instructions, less those inside skip."""
        n = 0
        while True:
            pc, sp, lr, ipsr = self.stub.step()
            if stop(pc, sp, ipsr):
                return n
            if pc == self.img.wfi:
                # Asleep until an interrupt: run over it (not counted, see the top).
                self.stub.run_to(pc + 2)
                continue
            f = self.img.owner(pc)
            if f in skip:
                continue
            n += 1
            if per is not None:
                per[f] = per.get(f, 0) + 1

    def byte_costs(self, pkt):
        """Send pkt; the instructions each of its bytes costs in the USART1 interrupt,
        from the handler's entry to thread mode or to the next byte's entry (the core
        tail-chains a pending USART1 interrupt at exception return)."""
        h = self.img.addr["usart1_handler"]
        self.stub.bp(h)
        self.drain()
        self.ser.sendall(pkt)
        costs = []
        self.stub.cont()
        while True:
            n = 1 + self.count(lambda p, s, ipsr: ipsr == 0 or p == h,
                               skip=("systick_handler",))
            pc, _, _, ipsr = self.stub.regs()
            if n == 1 and pc == h:
                # QEMU's stub at times reports the first step after stopping at the
                # handler's breakpoint at that same address: no instruction ran. Taken
                # as a byte, it shifted every later byte's figure by one (a frame's
                # last bytes then went into the next frame's list, or were never seen).
                continue
            costs.append(n)
            if len(costs) == len(pkt):
                break
            if pc != h:
                self.stub.cont()
        self.stub.bp(h, False)
        return costs

    def call(self, fn, skip=("plant_advance",)):
        """Stopped at fn's entry: its instructions until it returns (the entry counted)."""
        pc, sp, lr, _ = self.stub.regs()
        assert pc == self.img.addr[fn]
        ret = lr & ~1
        return 1 + self.count(lambda p, s, i: p == ret and s >= sp and i == 0, skip)

    def tick(self):
        a = self.img.addr["motion_poll"]
        while True:
            self.stub.run_to(a)
            n = self.call("motion_poll")
            if n > 60:  # a tick ran (otherwise motion_poll returned at once)
                return n

    def ticks(self, what, count, gap):
        got = []
        for _ in range(count):
            self.stub.run_for(gap)
            got.append(self.tick())
        self.within_budget = self.within_budget and max(got) <= 3600
        return "per control tick, %-8s average %5.0f, largest %5d instructions   " \
            "(target <= 3,600)" % (what, sum(got) / len(got), max(got))

    def run(self):
        img, stub = self.img, self.stub
        lines = []
        stub.run_for(0.5)  # boot: bootloader, then the application
        assert self.ask(frame(1, 0x03, 17, 0)) == OK, "WRITE heartbeat off"
        assert self.ask(frame(1, 0x03, 5, 0)) == OK, "WRITE return delay 0"

        # Per received byte, then the reply latency after the last.
        read = frame(1, 0x02, 0, 2)
        costs = self.byte_costs(read)
        per = {}
        tx = img.addr["tx_step"]

        def started(pc, sp, ipsr):  # the answer's first byte is written (tx_step)
            return pc == tx

        lat = costs[-1] + self.count(started, skip=("plant_advance", "systick_handler"),
                                     per=per)
        stub.run_for(0.1)
        answer = self.drain()
        assert answer == bytes.fromhex("D55D01040003525A"), answer.hex(" ")
        self.within_budget = sum(costs) / len(costs) < 100
        lines.append("instructions per received byte (READ frame, %d bytes): average %.0f, "
                     "largest %d   (target <= 60, must be < 100)" % (
                         len(costs), sum(costs) / len(costs), max(costs)))
        lines.append("  per byte: %s (the last one completes the frame)" %
                     " ".join(map(str, costs)))
        top = sorted(per.items(), key=lambda kv: -kv[1])[:5]
        lines.append("reply latency at return delay 0: %d instructions, %.0f us at %d MHz "
                     "(%.1f cycles per instruction)" % (
                         lat, lat * CYCLES_PER_INSTRUCTION / MHZ, MHZ, CYCLES_PER_INSTRUCTION))
        lines.append("  most in: " + ", ".join("%s %d" % kv for kv in top))

        # The receiver's worst cases (issue 25): every D5 5D a candidate. A SYNC WRITE to
        # servos 2-61 whose goals are all 0x5DD5 (60 candidates inside it, each with ID 3,
        # 4 ..., LEN D5); then the same with a bad checksum, and a PING behind it: its last
        # byte fails the frame and hands over to the first candidate inside it, whose 180
        # bytes so far move to a slot of their own.
        rich = frame(0xFE, 0x83, 30, 2, *[b for i in range(2, 62) for b in (i, 0xD5, 0x5D)])
        c = self.byte_costs(rich)
        lines.append("per received byte, SYNC WRITE with 60 D5 5D pairs (%d bytes): average "
                     "%.0f, largest %d" % (len(c), sum(c) / len(c), max(c)))
        time.sleep(0.05)
        broken = rich[:-1] + bytes([rich[-1] ^ 0xFF]) + frame(1, 0x01)
        c = self.byte_costs(broken)
        lines.append("per received byte, the same with a bad checksum, then a PING (%d "
                     "bytes): average %.0f, largest %d (the broken frame's last byte)" % (
                         len(c), sum(c) / len(c), max(c)))
        stub.run_for(0.1)
        self.drain()

        # Control ticks: at rest, homing, moving, holding.
        lines.append(self.ticks("at rest", 3, 0.05))
        assert self.ask(frame(1, 0x03, 24, 1)) == OK, "WRITE homing"
        lines.append(self.ticks("homing", 3, 0.2))
        for _ in range(60):  # homing: about 11 s of the firmware's clock
            st = self.ask(frame(1, 0x02, 24, 1), 0.5)
            if len(st) == 7 and st[5] >> 4 in (2, 3):
                break
        assert len(st) == 7 and st[5] >> 4 == 2, "homing did not finish: %s" % st.hex(" ")
        stub.run_for(0.5)
        assert self.ask(frame(1, 0x03, 30, 90, 0, 180, 0)) == OK, "WRITE goal 90"
        lines.append(self.ticks("moving", 3, 0.2))
        stub.run_for(2.5)
        lines.append(self.ticks("holding", 3, 0.05))

        # Re-plan: a new goal during a move.
        assert self.ask(frame(1, 0x03, 30, 200, 0, 180, 0)) == OK, "WRITE goal 200"
        stub.run_for(0.2)
        stub.bp(img.addr["command_written"])
        self.drain()
        self.ser.sendall(frame(1, 0x03, 30, 100, 0, 180, 0))
        stub.cont()
        stub.bp(img.addr["command_written"], False)
        n = self.call("command_written")
        m = self.tick()
        lines.append("per re-plan: command_written %d instructions, the tick after it %d" % (
            n, m))
        return lines


def main(elf):
    c = Cost(elf)
    try:
        lines = c.run()
    finally:
        c.close()
    for line in lines:
        print(line, flush=True)
    return 0 if c.within_budget else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else
                  os.path.join(REPO, "build", "qemu", "servo-qemu.elf")))
