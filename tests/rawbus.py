"""rawbus.py - the raw bytes the bus tests send and read (PROTOCOL.md §2-§3), written from
the spec and not from the SDK, so a test of the wire does not trust the code it checks:
instruction and status packets, the status packets found in a byte stream, a socket to a
servo's TCP port, and the tests' one way to report and fail. Shared by qemu_servo_test,
qemu_limits_test, qemu_resync and sim_burst."""
import socket
import sys

HEADER = (0xD5, 0x5D)


def packet(sid, ins, *par):
    """Instruction packet: D5 5D, ID, LEN (= params + 2), INS, params, CHK."""
    body = [sid, len(par) + 2, ins] + list(par)
    return bytes(list(HEADER) + body + [sum(body) & 0xFF])


def status(sid, err, *data):
    """Status packet: D5 5D, ID, LEN (= data + 2), ERR, data, CHK."""
    return packet(sid, err, *data)


def status_packets(data):
    """The well-formed status packets in data, in order."""
    out, i = [], 0
    while i + 4 <= len(data):
        if data[i] != HEADER[0] or data[i + 1] != HEADER[1]:
            i += 1
            continue
        n = 4 + data[i + 3]
        p = data[i:i + n]
        if len(p) == n and data[i + 3] >= 2 and sum(p[2:-1]) & 0xFF == p[-1]:
            out.append(p)
            i += n
        else:
            i += 1
    return out


def connect(port, timeout=2):
    """A socket to 127.0.0.1:port, every byte sent at once (no Nagle)."""
    sock = socket.create_connection(("127.0.0.1", port), timeout=timeout)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return sock


def reporter(name):
    """(fail, say) for a test named name: fail prints to stderr and exits 1."""
    def fail(msg):
        print(f"{name}: FAIL: {msg}", file=sys.stderr, flush=True)
        sys.exit(1)

    def say(msg):
        print(f"{name}: {msg}", flush=True)
    return fail, say


def on_qemu(name, deadline_s, body, *qemu_args):
    """Run body(q) against one QemuServo (tools/qemu_servo.py; qemu_args: image and ELF)
    booted and answering PING, the whole run bounded by deadline_s; fail on anything the
    MCU does not survive (QEMU exits on a reset or fault), print QEMU's own words, then
    PASS with the time taken."""
    import signal
    import time
    from qemu_servo import QemuServo  # tools/ on sys.path: the QEMU tests put it there
    fail, say = reporter(name)
    signal.signal(signal.SIGALRM, lambda *_: fail(f"over {deadline_s:.0f} s"))
    signal.setitimer(signal.ITIMER_REAL, deadline_s)
    t0 = time.monotonic()
    try:
        q = QemuServo(*qemu_args)
    except (FileNotFoundError, RuntimeError) as e:
        fail(str(e))
    try:
        if not q.wait_ready():
            fail("the image did not answer PING within 10 s of boot")
        body(q)
        if not q.alive():
            fail("QEMU exited: the MCU reset or faulted")
    finally:
        out = q.stop()
        if out:
            say("QEMU said: " + out)
    say(f"PASS ({time.monotonic() - t0:.0f} s)")
