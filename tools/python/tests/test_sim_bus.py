"""servo-sim as a bus (tools/sim/bus.h): the baud rate as an RFC 2217 client sees it, two
servos on the wire at once, and the TCP side's connection handling. Raw tcp:// keeps the
old contract (every baud heard), which test_sim.py and the rest of the suite exercise."""

import os
import socket
import subprocess
import sys
import time

import pytest

from conftest import PYROOT
from servobus import Bus, BusTimeout

pytest.importorskip("serial", reason="rfc2217:// needs pyserial (python3-serial)")


def servoctl(*args, timeout=60):
    env = dict(os.environ, PYTHONPATH=PYROOT)
    env.pop("SERVOBUS_PORT", None)
    p = subprocess.run([sys.executable, "-m", "servobus", *args], capture_output=True,
                       text=True, env=env, timeout=timeout)
    return p.returncode, p.stdout, p.stderr


def rfc2217(sim):
    return "rfc2217://127.0.0.1:%d" % sim.port


def packet(servo_id, ins, *params):
    body = [servo_id, len(params) + 2, ins, *params]
    return bytes([0xD5, 0x5D, *body, sum(body) & 0xFF])


def status(servo_id, err, *params):
    return packet(servo_id, err, *params)  # the same shape (PROTOCOL.md §3)


PING = 0x01
READ = 0x02
WRITE = 0x03
REG_ID, REG_BAUD = 3, 4


class Raw:
    """A raw tcp:// client sending bytes and collecting what it hears."""

    def __init__(self, sim):
        self.s = socket.create_connection(("127.0.0.1", sim.port), timeout=2)
        self.s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def transact(self, data, wait=0.15):
        self.s.sendall(data)
        end, got = time.monotonic() + wait, b""
        while time.monotonic() < end:
            self.s.settimeout(max(0.001, end - time.monotonic()))
            try:
                chunk = self.s.recv(4096)
            except socket.timeout:
                break
            if not chunk:
                break
            got += chunk
        return got

    def close(self):
        self.s.close()


# ---- the baud rate, as a UART host sees it (RFC 2217) --------------------------------

def test_scan_all_bauds_over_rfc2217_finds_three_bauds(sim_factory):
    """Issue 13: an arm at 9600 (its default), a foot moved to 38400, a base at 115200
    (its default): `scan --all-bauds` over rfc2217:// finds each at its own baud."""
    sim = sim_factory("1:arm", "2:foot", "3:base")
    raw = Raw(sim)  # raw tcp:// is heard at every baud: configure through it
    assert raw.transact(packet(2, WRITE, REG_BAUD, 3)) == status(2, 0)
    raw.close()
    rc, out, err = servoctl("--port", rfc2217(sim), "scan", "--all-bauds", timeout=90)
    assert rc == 0, (out, err)
    assert "3 servos found at every baud" in out, out
    rows = {int(r[0]): (r[1], r[2]) for r in (line.split() for line in out.splitlines()[2:])}
    assert rows == {1: ("arm", "9600"), 2: ("foot", "38400"), 3: ("base", "115200")}, out


def test_one_baud_scan_over_rfc2217_hears_only_that_baud(sim_factory):
    sim = sim_factory("1:arm", "3:base")
    rc, out, err = servoctl("--port", rfc2217(sim), "scan")
    assert rc == 0, (out, err)
    assert "1 servo found at 9600 baud" in out
    rc, out, err = servoctl("--port", rfc2217(sim), "--baud", "115200", "scan")
    assert rc == 0, (out, err)
    assert "1 servo found at 115200 baud" in out and " base " in out


def test_wrong_baud_gets_the_hint(sim_factory):
    """The user's classic: the host at 9600, the servo (a base) at 115200."""
    sim = sim_factory("3:base")
    rc, out, err = servoctl("--port", rfc2217(sim), "--id", "3", "ping")
    assert rc == 1, (out, err)
    assert "no status packet from ID 3 at 9600 baud" in err, err
    assert "wrong ID or baud? try `servoctl scan --all-bauds`" in err, err
    rc, out, err = servoctl("--port", rfc2217(sim), "--baud", "115200", "--id", "3", "ping")
    assert rc == 0 and "ID 3: present" in out, (out, err)


def test_baud_change_then_the_host_follows(sim_factory):
    sim = sim_factory("1:arm")
    with Bus(rfc2217(sim)) as bus:
        assert bus.ping(1) == 0
        bus.write(1, "baud_rate", 4)  # 115200; answered at the old baud (§1)
        with pytest.raises(BusTimeout, match="wrong ID or baud"):
            bus.ping(1)  # the servo now listens at 115200: the host's 9600 is garbage
        bus.set_baud(115200)
        assert bus.ping(1) == 0
        assert bus.read(1, "baud_rate") == 4
        bus.write(1, "baud_rate", 2)  # back to 9600
        bus.set_baud(9600)
        assert bus.read(1, "id") == 1
    # A new client starts at 9600 again: it reaches the servo at its register's baud.
    rc, out, err = servoctl("--port", rfc2217(sim), "--id", "1", "ping")
    assert rc == 0, (out, err)


def test_baud_change_right_after_a_broadcast_write(sim_factory):
    """The WRITE's bytes are still on the line at 9600 when the client asks for the new
    baud: they go out at the baud they were sent at, and the servos follow."""
    sim = sim_factory("1:arm", "2:arm")
    with Bus(rfc2217(sim)) as bus:
        bus.write(254, {"baud_rate": 10, "return_delay": 0})  # broadcast: no answer
        bus.set_baud(1792000)
        assert [f.id for f in bus.scan()] == [1, 2]


def test_an_answer_held_by_a_frame_arriving(sim_factory):
    """Listen before talk: an answer due while a frame arrives waits for the receiver to
    fall idle (here the §1 gap abandons the half frame). The simulator runs on meanwhile
    (it once spun on the held answer for ever)."""
    sim = sim_factory("1:arm")
    raw = Raw(sim)
    got = raw.transact(packet(1, PING) + packet(1, READ, 36, 2)[:4], wait=0.3)
    assert got == status(1, 0x01, 0x00), got.hex(" ")
    assert raw.transact(packet(1, PING)) == status(1, 0x01, 0x00)
    raw.close()


def test_raw_tcp_still_hears_every_baud(sim_factory):
    sim = sim_factory("1:arm", "3:base")
    with Bus(sim.url) as bus:  # tcp://: the host has no baud
        assert bus.ping(1) == 0 and bus.ping(3) == 0
        bus.write(1, "baud_rate", 10)  # 1792000
        assert bus.ping(1) == 0
        bus.write(1, "baud_rate", 2)


def test_rfc2217_data_with_0xff_is_escaped_both_ways(sim_factory):
    """0xFF in the data stream is doubled on the Telnet connection (pyserial undoes it):
    a WRITE of 255 and a READ of it back go through."""
    sim = sim_factory("1:arm")
    with Bus(rfc2217(sim)) as bus:
        bus.write(1, "return_delay", 255)
        assert bus.read(1, "return_delay") == 255
        bus.write(1, "return_delay", 0)


# ---- two talkers at once (issue 20) -------------------------------------------------

def make_duplicate(raw, old_id, new_id):
    """Move a servo onto an ID another servo has: its answer comes at the old ID."""
    assert raw.transact(packet(old_id, WRITE, REG_ID, new_id)) == status(old_id, 0)


def test_two_answers_at_once_garble(sim_factory):
    """An arm and a wrist both at ID 1, 9600 baud. A PING is answered by both with the
    same bytes within microseconds: they superimpose into one clean answer (the wire is
    the AND of the talkers). A READ of the model number is answered with different
    bytes at the same time: what arrives is garbage, never either answer."""
    sim = sim_factory("1:arm", "2:wrist")
    raw = Raw(sim)
    make_duplicate(raw, 2, 1)
    assert raw.transact(packet(1, PING)) == status(1, 0x01, 0x00)
    arm = status(1, 0, 2, 0)  # model numbers (boards.c)
    for _ in range(3):
        got = raw.transact(packet(1, READ, 0, 2))
        assert got, "both answered: the line cannot be silent"
        assert status(1, 0) not in got
        assert got[:7] != arm and got != got[:0]
        assert not (len(got) == 8 and sum(got[2:7]) & 0xFF == got[7]), got.hex(" ")
    raw.close()


def test_duplicates_at_high_baud_garble_even_identical_answers(sim_factory):
    """At 1792000 baud a bit is 0.56 us, and two MCUs start their answers microseconds
    apart (main-loop latency, bus.h): two identical arms on one ID garble even a PING."""
    sim = sim_factory("1:arm", "2:arm")
    raw = Raw(sim)
    for i in (1, 2):
        assert raw.transact(packet(i, WRITE, REG_BAUD, 10)) == status(i, 0)
    make_duplicate(raw, 2, 1)
    answers = [raw.transact(packet(1, PING), wait=0.05) for _ in range(10)]
    clean = sum(a == status(1, 0x01, 0x00) for a in answers)
    assert clean < 5, [a.hex(" ") for a in answers]
    raw.close()


def test_servos_hear_each_other(sim_factory):
    """A servo hears the others' answers on the line, as on RS485. A PING answer has the
    shape of a PING instruction with one parameter (§3, §4.1), so a servo with the same
    ID and a longer return delay takes the first one's answer for an instruction to it:
    it answers that as well as the host's PING (what a real bus does with duplicate IDs).
    """
    sim = sim_factory("1:arm", "2:arm")
    raw = Raw(sim)
    assert raw.transact(packet(2, WRITE, 5, 100)) == status(2, 0)  # return delay 50 ms
    make_duplicate(raw, 2, 1)
    got = raw.transact(packet(1, PING), wait=0.3)
    answers = [got[i:i + 7] for i in range(0, len(got), 7)]
    assert answers[0] == status(1, 0x01, 0x00), got.hex(" ")  # the arm with delay 0
    assert len(answers) >= 2, got.hex(" ")  # the other one answered more than the host
    raw.close()


# ---- connections (issue 19) ---------------------------------------------------------

def test_rapid_reconnects_never_stall(sim_factory):
    """200 connect/PING/close cycles, as scripts running servoctl in a loop do: with a
    backlog of 1 about one connect in ten waited for a SYN retransmission (1 s)."""
    sim = sim_factory("1:arm")
    worst = 0.0
    start = time.monotonic()
    for _ in range(200):
        t0 = time.monotonic()
        s = socket.create_connection(("127.0.0.1", sim.port), timeout=3)
        worst = max(worst, time.monotonic() - t0)
        s.close()
    assert worst < 0.5, worst
    for _ in range(20):
        raw = Raw(sim)
        assert raw.transact(packet(1, PING)) == status(1, 0x01, 0x00)
        raw.close()
    assert time.monotonic() - start < 30


def test_half_a_frame_is_gone_with_its_client(sim_factory):
    """A client that disconnects mid-frame leaves nothing in the servos' receivers: the
    next client's first answer is the answer to its own first packet."""
    sim = sim_factory("1:arm")
    first = Raw(sim)
    first.s.sendall(packet(1, READ, 36, 2)[:5])  # D5 5D 01 04 02: LEN says 3 more
    time.sleep(0.005)
    first.close()
    second = Raw(sim)  # well within the §1 gap (20.8 ms at 9600)
    assert second.transact(packet(1, PING)) == status(1, 0x01, 0x00)
    second.close()


def test_half_a_frame_over_rfc2217_too(sim_factory):
    sim = sim_factory("1:arm")
    import serial
    port = serial.serial_for_url(rfc2217(sim), baudrate=9600, timeout=0.2)
    port.write(packet(1, READ, 36, 2)[:5])
    port.close()
    with Bus(rfc2217(sim)) as bus:
        assert bus.ping(1) == 0


def test_rfc2217_negotiation_by_hand(sim_factory):
    """The Telnet side without pyserial: the server asks for BINARY both ways, agrees to
    COM-PORT-OPTION, refuses ECHO, answers a baud query with 9600, a SET-BAUDRATE with
    the new baud, and a data size of 7 with the 8 the bus has."""
    IAC, SB, SE, WILL, WONT, DO = 0xFF, 0xFA, 0xF0, 0xFB, 0xFC, 0xFD
    sim = sim_factory("1:arm")
    s = socket.create_connection(("127.0.0.1", sim.port), timeout=2)

    def exchange(data, want):
        s.sendall(bytes(data))
        got, end = b"", time.monotonic() + 1
        while not all(bytes(w) in got for w in want) and time.monotonic() < end:
            s.settimeout(max(0.01, end - time.monotonic()))
            try:
                got += s.recv(4096)
            except socket.timeout:
                break
        for w in want:
            assert bytes(w) in got, (bytes(w).hex(" "), got.hex(" "))
        return got

    exchange([IAC, WILL, 44, IAC, DO, 1],
             [[IAC, DO, 0], [IAC, WILL, 0], [IAC, DO, 44], [IAC, WONT, 1]])
    exchange([IAC, SB, 44, 1, 0, 0, 0, 0, IAC, SE], [[IAC, SB, 44, 101, 0, 0, 0x25, 0x80, IAC, SE]])
    exchange([IAC, SB, 44, 2, 7, IAC, SE], [[IAC, SB, 44, 102, 8, IAC, SE]])
    exchange([IAC, SB, 44, 1, 0, 1, 0xC2, 0, IAC, SE],  # 115200
             [[IAC, SB, 44, 101, 0, 1, 0xC2, 0, IAC, SE]])
    got = exchange(packet(1, PING), [])  # the arm listens at 9600: garbage, no answer
    assert status(1, 0x01, 0x00) not in got
    s.close()


# ---- state files --------------------------------------------------------------------

def test_state_file_from_before_the_image_slots_keeps_its_settings(sim_factory, tmp_path):
    """A 4 KiB state file (the store only, as servo-sim wrote before the image slots) is
    extended in place once, with erased pages: the settings stay, the application slot
    gets the factory image, and the file is an ordinary one from then on."""
    sim = sim_factory("5:arm", state_dir=tmp_path)
    with Bus(sim.url) as bus:
        bus.write(5, "return_delay", 3)
    sim.stop()
    f = tmp_path / "servo-5-arm.flash"
    full = f.stat().st_size
    with open(f, "r+b") as fh:
        fh.truncate(4096)
    sim = sim_factory("5:arm", state_dir=tmp_path)
    assert f.stat().st_size == full
    with Bus(sim.url) as bus:
        assert bus.read(5, "return_delay") == 3
        assert bus.read(5, "firmware_version") == 1
    assert sim.stop() == 0


@pytest.mark.parametrize("scheme", ["tcp", "rfc2217"])
def test_a_broadcast_right_before_close_still_reaches_every_servo(sim_factory, scheme):
    """A broadcast is answered by nobody, so nothing held the port open until its bytes
    were on the wire: closed at once, servo-sim dropped them (it forgets what a client
    that left had not delivered at its servos' baud) and the write was lost, as
    make bench's studio polling found. Bus.close() now drains as a serial port does."""
    sim = sim_factory("1:arm", "2:foot")
    with Bus(sim.url.replace("tcp://", scheme + "://"), baud=9600) as bus:
        bus.write(254, {"acceleration": 77})
    with Bus(sim.url) as bus:
        assert [bus.read(i, "acceleration") for i in (1, 2)] == [77, 77]
