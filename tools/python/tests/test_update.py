"""Firmware update over the bus (PROTOCOL.md §10): the frames, the SDK's retries against
a scripted servo, and Bus.update / servoctl update end to end against servo-sim (the
image module and tools/fwstamp.py: test_image.py)."""

import os
import signal
import socket
import struct
import subprocess
import sys
import threading

import pytest

from conftest import PYROOT
from test_image import corrupt
from servobus import (Bus, ImageError, ServoBusError, UpdateError, UpdateRefused,
                      UpdateTimeout, VARIANTS)
from servobus import image as I
from servobus import protocol as P

ARM = VARIANTS["arm"].model_number
FOOT = VARIANTS["foot"].model_number
FACTORY_VERSION = 1  # what a freshly started servo-sim servo runs (SERVO_FW_VERSION)


# ---- the frames ---------------------------------------------------------------------

def test_frames_match_the_vector_rows():
    assert P.update_enter(1) == bytes.fromhex("D55D0103FFFCFF")
    assert P.update_eof(1) == bytes.fromhex("D55D0104FFFE0406")


def test_crc16_xmodem():
    assert P.crc16_xmodem(b"123456789") == 0x31C3
    assert P.crc16_xmodem(b"") == 0


def _check_sum(frame):
    assert frame[:2] == b"\xD5\x5D" and frame[-1] == sum(frame[2:-1]) & 0xFF


def test_header_and_end_of_batch_frames():
    h = P.update_header(5, 16384)
    assert len(h) == 140 and h[2:9] == bytes([5, 0x88, 0xFF, 0xFE, 0x01, 0x00, 0xFF])
    data = h[9:137]
    assert data == b"\x00\x00\x40\x00" + bytes(124)
    assert h[137:139] == P.crc16_xmodem(data).to_bytes(2, "big")
    _check_sum(h)
    end = P.update_end(5)
    assert end[9:137] == bytes(128) and end[137:139] == b"\0\0" and len(end) == 140
    _check_sum(end)


def test_data_frames():
    chunk = bytes(range(256)) * 4
    f = P.update_data(1, 3, chunk)
    assert len(f) == 1036 and f[2:9] == bytes([1, 0xFF, 0xFF, 0xFE, 0x02, 3, 0xFC])
    assert f[9:1033] == chunk and f[1033:1035] == P.crc16_xmodem(chunk).to_bytes(2, "big")
    _check_sum(f)
    last = P.update_data(1, 16, b"\x11" * 100)
    assert last[9:1033] == b"\x11" * 100 + b"\xFF" * 924 and len(last) == 1036
    _check_sum(last)


def test_update_frames_in_order():
    data = I.build(5000, 2, ARM)
    frames = P.update_frames(1, data)
    assert [s for s, _, _ in frames] == ["enter", "header block"] + [
        "data block %d" % n for n in range(1, 6)] + ["end of file", "end of batch"]
    assert b"".join(f[9:1033] for s, f, _ in frames if s.startswith("data")) == \
        data + b"\xFF" * (5 * 1024 - 5000)
    assert sum(n for _, _, n in frames) == 5000


# ---- retries and refusals against a scripted servo ----------------------------------

class FakeServo:
    """A TCP server playing one servo: PING, READ of the table's first bytes, and the §10
    frames (ACKs everything in order). `script` maps (step, attempt) to what to do
    instead: "drop" (no answer), "nak", "can", "echo" (echo the frame, then answer),
    "ins" (an instruction error). `ping` False plays a servo in its bootloader."""

    def __init__(self, servo_id=1, model=ARM, version=1, ping=True, script=None):
        self.servo_id, self.model, self.version, self.ping = servo_id, model, version, ping
        self.script = dict(script or {})
        self.seen = []  # steps in arrival order
        self.image = bytearray()
        self.length = 0
        self.srv = socket.socket()
        self.srv.bind(("127.0.0.1", 0))
        self.srv.listen(1)
        self.url = "tcp://127.0.0.1:%d" % self.srv.getsockname()[1]
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _answer(self, conn, err, params):
        body = bytes([self.servo_id, len(params) + 2, err]) + bytes(params)
        conn.sendall(b"\xD5\x5D" + body + bytes([sum(body) & 0xFF]))

    def _frames(self, conn):
        buf = bytearray()
        while True:
            data = conn.recv(65536)
            if not data:
                return
            buf += data
            while True:
                i = buf.find(b"\xD5\x5D")
                if i < 0 or len(buf) < i + 5:
                    break
                del buf[:i]
                if buf[3] == 0xFF and len(buf) < 7:
                    break
                if buf[3] == 0xFF and buf[4] == 0xFF and buf[6] == 2:
                    total = 4 + 1031 + 1
                else:
                    total = 4 + buf[3]
                if len(buf) < total:
                    break
                yield bytes(buf[:total])
                del buf[:total]

    def _step(self, f):
        if f[4] != 0xFF:
            return None
        if f[5] == 0xFC:
            return "enter"
        kind = f[6]
        if kind == 1:
            return "end of batch" if not any(f[9:137]) else "header block"
        if kind == 2:
            return "data block %d" % f[7]
        return "end of file"

    def _run(self):
        conn, _ = self.srv.accept()
        with conn:
            for f in self._frames(conn):
                if f[2] != self.servo_id:
                    continue
                ins = f[4]
                if ins == P.PING:
                    if self.ping:
                        self._answer(conn, 0x01, [0])
                    continue
                if ins == P.READ:
                    table = struct.pack("<HB", self.model, self.version) + bytes(50)
                    self._answer(conn, 0, table[f[5]:f[5] + f[6]])
                    continue
                step = self._step(f)
                if step is None:
                    self._answer(conn, 0x20, [])
                    continue
                attempt = self.seen.count(step)
                self.seen.append(step)
                what = self.script.get((step, attempt))
                if what == "drop":
                    continue
                if what == "echo":
                    conn.sendall(f)
                if what == "ins":
                    self._answer(conn, 0x20, [])
                    continue
                if what in ("nak", "can"):
                    self._answer(conn, 0, [P.NAK if what == "nak" else P.CAN])
                    continue
                if step == "header block":
                    self.length = int.from_bytes(f[9:13], "big")
                if step.startswith("data block"):
                    n = f[7]
                    self.image[(n - 1) * 1024:n * 1024] = f[9:1033]
                if step == "end of batch":
                    self.version = I.parse(bytes(self.image[:self.length])).version
                self._answer(conn, 0, {"enter": [P.READY], "header block": [P.ACK, P.READY],
                                       "end of file": [P.ACK, P.READY]}.get(step, [P.ACK]))

    def close(self):
        self.srv.close()


@pytest.fixture
def fake():
    servos = []

    def start(**kw):
        s = FakeServo(**kw)
        servos.append(s)
        return s

    yield start
    for s in servos:
        s.close()


def _update(servo, data, timeout=0.15, **kw):
    notes, marks = [], []
    with Bus(servo.url, timeout=timeout) as bus:
        version = bus.update(1, data, progress=lambda *a: marks.append(a),
                             notify=notes.append, restart_timeout=1.0, **kw)
    return version, notes, marks


def test_scripted_update_goes_through(fake):
    servo = fake()
    data = I.build(3000, 9, ARM)
    version, notes, marks = _update(servo, data)
    assert version == 9 and not notes
    assert bytes(servo.image[:3000]) == data and servo.image[3000:] == b"\xFF" * 72
    assert servo.seen == ["enter", "header block", "data block 1", "data block 2",
                          "data block 3", "end of file", "end of batch"]
    assert marks == [(0, 3, 0, 3000), (1, 3, 1024, 3000), (2, 3, 2048, 3000),
                     (3, 3, 3000, 3000)]


def test_silence_and_nak_are_resent(fake):
    servo = fake(script={("enter", 0): "drop", ("data block 2", 0): "nak",
                         ("data block 2", 1): "drop", ("end of file", 0): "echo",
                         ("end of batch", 0): "drop"})
    version, _, _ = _update(servo, I.build(3000, 9, ARM))
    assert version == 9
    assert servo.seen.count("data block 2") == 3 and servo.seen.count("enter") == 2
    assert servo.seen.count("end of batch") == 2 and servo.seen.count("end of file") == 1


def test_gives_up_after_the_retries(fake):
    servo = fake(script={("data block 1", i): "drop" for i in range(10)})
    with pytest.raises(UpdateTimeout) as e:
        _update(servo, I.build(3000, 9, ARM), retries=2)
    assert e.value.step == "data block 1" and e.value.servo_id == 1
    assert "no answer from ID 1" in str(e.value) and "after 3 tries" in str(e.value)
    assert servo.seen.count("data block 1") == 3

    servo = fake(script={("header block", i): "nak" for i in range(10)})
    with pytest.raises(UpdateError) as e:
        _update(servo, I.build(3000, 9, ARM), retries=3)
    assert not isinstance(e.value, UpdateTimeout)
    assert "header block failed 4 times" in str(e.value) and "NAK" in str(e.value)


def test_can_raises_update_refused(fake):
    servo = fake(script={("data block 1", 0): "can"})
    with pytest.raises(UpdateRefused) as e:
        _update(servo, I.build(3000, 9, ARM))
    assert e.value.step == "data block 1"
    assert "refused the update at the data block 1 (CAN)" in str(e.value)
    assert "keeps its running firmware" in str(e.value)
    assert servo.seen[-1] == "data block 1"  # nothing sent after the CAN


def test_firmware_without_update_support(fake):
    servo = fake(script={("enter", 0): "ins"})
    with pytest.raises(UpdateError, match="instruction error.*does not take updates"):
        _update(servo, I.build(3000, 9, ARM))


def test_checks_before_sending(fake):
    servo = fake(model=FOOT)
    with pytest.raises(ImageError, match="model 0x5202"):
        _update(servo, I.build(3000, 9, ARM))
    with pytest.raises(ImageError, match="bad CRC"):
        _update(servo, corrupt(I.build(3000, 9, FOOT), 2000))
    assert "enter" not in servo.seen


def test_a_servo_in_its_bootloader_is_updated_with_a_note(fake):
    servo = fake(ping=False, model=FOOT)
    with Bus(servo.url, timeout=0.15) as bus:
        notes = []
        with pytest.raises(UpdateError) as e:  # it never answers PING afterwards either
            bus.update(1, I.build(3000, 9, ARM), notify=notes.append, restart_timeout=0.5)
    # it stays in update mode after the image: what a servo whose new image does not
    # confirm itself (3 unconfirmed starts) looks like to the host
    assert e.value.step == "restart" and bus.update_mode
    assert "does not start it: it waits in its bootloader's update mode" in str(e.value)
    assert "send a good image" in str(e.value)
    assert len(notes) == 1 and "answers the update handshake" in notes[0]
    assert "bootloader" in notes[0]
    assert servo.seen[-2:] == ["end of batch", "enter"]  # the image, then the probe


# ---- servo-sim ----------------------------------------------------------------------

def test_update_through_servo_sim(sim_factory):
    sim = sim_factory("1:arm", "2:foot")
    data = I.build(16384, version=7, model=ARM)
    with Bus(sim.url) as bus:
        assert bus.read(1, "firmware_version") == FACTORY_VERSION
        bus.write(1, "return_delay", 4)  # EEPROM: survives the update
        marks = []
        assert bus.update(1, data, progress=lambda *a: marks.append(a)) == 7
        assert marks[0] == (0, 16, 0, 16384) and marks[-1] == (16, 16, 16384, 16384)
        assert len(marks) == 17
        assert bus.ping(1) == 0
        assert bus.read_many(1, ["model_number", "firmware_version", "return_delay"]) == {
            "model_number": ARM, "firmware_version": 7, "return_delay": 4}
        bus.write(1, "acceleration", 50)
        assert bus.read(1, "acceleration") == 50
        assert bus.read(2, "firmware_version") == FACTORY_VERSION  # the other one untouched


def test_update_answers_whatever_the_status_return_level(sim_factory):
    sim = sim_factory("4:foot")
    with Bus(sim.url) as bus:
        bus.write(4, "status_return_level", 1)  # READ (and PING) only
        assert bus.update(4, I.build(2000, 3, FOOT)) == 3
        assert bus.read(4, "status_return_level") == 1


def test_bad_crc_is_refused_by_the_servo(sim_factory):
    sim = sim_factory("1:arm")
    bad = corrupt(I.build(4096, 7, ARM), 3000)  # 4 blocks at 9600 baud: 5 s, not 18
    with Bus(sim.url) as bus:
        with pytest.raises(ImageError, match="bad CRC"):
            bus.update(1, bad)
        with pytest.raises(UpdateRefused) as e:
            bus.update(1, bad, check=False)
        assert e.value.step == "end of batch" and "failed its check" in str(e.value)
        assert bus.ping(1) == 0 and bus.read(1, "firmware_version") == FACTORY_VERSION
        assert bus.update(1, I.build(4096, 8, ARM)) == 8  # and a good one still goes in


@pytest.mark.parametrize("make,step", [
    (lambda: I.build(16384, 7, FOOT), "data block 1"),  # another board's image
    (lambda: I.build(16384, 7, ARM)[:12000], None),      # truncated
    (lambda: I.build(I.MAX_BYTES, 7, ARM) + bytes(1), "header block"),  # too large
])
def test_the_servo_refuses_what_it_cannot_take(sim_factory, make, step):
    sim = sim_factory("1:arm")
    with Bus(sim.url) as bus:
        with pytest.raises(UpdateRefused) as e:
            bus.update(1, make(), check=False)
        if step:
            assert e.value.step == step
        assert bus.ping(1) == 0 and bus.read(1, "firmware_version") == FACTORY_VERSION


def servoctl(*args):
    env = dict(os.environ, PYTHONPATH=PYROOT)
    env.pop("SERVOBUS_PORT", None)
    p = subprocess.run([sys.executable, "-m", "servobus", *args], capture_output=True,
                       text=True, env=env, timeout=60)
    return p.returncode, p.stdout, p.stderr


def test_servoctl_update(sim_factory, tmp_path):
    sim = sim_factory("3:wrist")
    good = tmp_path / "wrist.img"
    good.write_bytes(I.build(4096, 5, VARIANTS["wrist"].model_number))  # 4 blocks: 5 s
    rc, out, err = servoctl("--port", sim.url, "--id", "3", "update", str(good))
    assert rc == 0, err
    assert "ID 3: updated in" in out and "now runs firmware version 5" in out
    assert "model 0x5204 (wrist), version 5" in err and "ID 3 runs firmware version 1" in err
    assert " 4/4 blocks,   4096/4096 bytes" in err
    rc, out, _ = servoctl("--port", sim.url, "--id", "3", "get", "firmware_version", "--raw")
    assert rc == 0 and out.strip() == "5"

    bad = tmp_path / "bad.img"
    bad.write_bytes(corrupt(good.read_bytes(), 3000))
    rc, out, err = servoctl("update", str(bad), "--port", sim.url, "--id", "3")
    assert rc == 2 and err.startswith("servoctl: bad CRC") and err.count("\n") == 1
    rc, out, err = servoctl("update", str(bad), "--no-check", "--port", sim.url, "--id", "3")
    assert rc == 1, err
    assert "servoctl: ID 3 refused the update at the end of batch (CAN)" in err
    rc, out, err = servoctl("update", str(tmp_path / "none.img"), "--port", sim.url)
    assert rc == 2 and "cannot read" in err
    other = tmp_path / "arm.img"
    other.write_bytes(I.build(4096, 5, ARM))
    rc, out, err = servoctl("--port", sim.url, "--id", "3", "update", str(other))
    assert rc == 2 and "the servo is model 0x5204 (wrist)" in err
    rc, out, _ = servoctl("--port", sim.url, "--id", "3", "get", "firmware_version", "--raw")
    assert out.strip() == "5"


APP_SLOT = 4 * 1024  # byte offset of the application slot in a --state-dir flash file


def test_a_cut_during_the_update_keeps_the_old_firmware(sim_factory, tmp_path):
    state = tmp_path / "state"
    sim = sim_factory("1:arm", state_dir=state)

    def cut(done, total, nbytes, total_bytes):
        if done == 2:
            sim.stop(signal.SIGKILL)  # a power cut half-way through the data blocks

    with Bus(sim.url) as bus:
        with pytest.raises(ServoBusError):
            bus.update(1, I.build(4096, 7, ARM), progress=cut, retries=1)
    sim = sim_factory("1:arm", state_dir=state)
    with Bus(sim.url) as bus:
        assert bus.read(1, "firmware_version") == FACTORY_VERSION
        assert bus.update(1, I.build(4096, 7, ARM)) == 7
    sim.stop()
    sim = sim_factory("1:arm", state_dir=state)  # the new image survives a power cycle
    with Bus(sim.url) as bus:
        assert bus.read(1, "firmware_version") == 7


def test_a_servo_in_update_mode_is_updated(sim_factory, tmp_path):
    state = tmp_path / "state"
    sim_factory("2:foot", state_dir=state).stop()
    flash = state / "servo-2-foot.flash"
    data = bytearray(flash.read_bytes())
    data[APP_SLOT + 5000] ^= 0xFF  # a damaged application: the bootloader stays in charge
    flash.write_bytes(data)
    sim = sim_factory("2:foot", state_dir=state)
    with Bus(sim.url) as bus:
        assert not bus.present(2)  # update mode answers only the update frames
        notes = []
        assert bus.update(2, I.build(3000, 4, FOOT), notify=notes.append) == 4
        assert len(notes) == 1 and "bootloader" in notes[0]
        assert bus.ping(2) == 0 and bus.read(2, "model_number") == FOOT
