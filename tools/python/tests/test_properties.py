"""Issue 15: property tests (Hypothesis) for the SDK's frame parser and builders, and for
the Bus reading arbitrary bytes off the wire."""

import os
import time

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import servobus.identity
import servobus.link
from servobus import Bus, ServoBusError
from servobus import image as I
from servobus import protocol as P

# Bounded for `make test`; SERVOBUS_EXAMPLES=N runs N examples per property.
EXAMPLES = int(os.environ.get("SERVOBUS_EXAMPLES", "80"))
PROFILE = settings(max_examples=EXAMPLES, deadline=None,
                   suppress_health_check=[HealthCheck.too_slow])

ids = st.integers(0, P.ID_MAX)
any_id = st.integers(0, P.BROADCAST)
params = st.binary(max_size=253)
# Bytes that can sit between frames: no header inside, and no trailing D5 that a
# frame's 5D could complete... into a header of its own: then the parser's hunt is what
# is under test, not the garbage.
garbage = st.binary(max_size=40).filter(lambda b: P.HEADER not in b and
                                        not b.endswith(P.HEADER[:1]))


def parse_all(data, cuts=()):
    """Every packet of data, fed in pieces cut at the given offsets."""
    parser = P.StatusParser()
    out, last = [], 0
    for cut in sorted(set(c % (len(data) + 1) for c in cuts)) + [len(data)]:
        out += parser.feed(data[last:cut])
        last = cut
    return out, parser


@st.composite
def built_frames(draw):
    """Any frame the SDK builds: an instruction packet, or one of the §10 frames."""
    kind = draw(st.sampled_from(["instruction", "enter", "header", "data", "eof", "end"]))
    servo_id = draw(ids)
    if kind == "instruction":
        return P.instruction(draw(any_id), draw(st.integers(0, 255)), draw(params))
    if kind == "enter":
        return P.update_enter(servo_id)
    if kind == "header":
        return P.update_header(servo_id, draw(st.integers(0, 0xFFFFFFFF)))
    if kind == "data":
        return P.update_data(servo_id, draw(st.integers(0, 255)),
                             draw(st.binary(max_size=P.UPDATE_BLOCK_DATA)))
    if kind == "eof":
        return P.update_eof(servo_id)
    return P.update_end(servo_id)


@PROFILE
@given(st.binary(max_size=3000), st.lists(st.integers(0, 3000), max_size=8))
def test_any_byte_stream_parses_without_raising(data, cuts):
    packets, parser = parse_all(data, cuts)
    for pkt in packets:  # whatever came out is a well-formed packet, checksum judged
        assert pkt.raw[:2] == P.HEADER and len(pkt.raw) >= 6
        assert pkt.ok == (sum(pkt.raw[2:-1]) & 0xFF == pkt.raw[-1])
    assert parser.pending() <= len(data)


@PROFILE
@given(built_frames(), st.lists(st.integers(0, 1100), max_size=5))
def test_every_built_frame_parses_back_to_itself(frame, cuts):
    packets, parser = parse_all(frame, cuts)
    assert [p.raw for p in packets] == [frame] and packets[0].ok
    assert parser.pending() == 0 and parser.skipped == 0
    assert packets[0].id == frame[2] and packets[0].err == frame[4]
    assert packets[0].params == frame[5:-1]


@PROFILE
@given(st.lists(st.tuples(garbage, built_frames()), min_size=1, max_size=5), garbage,
       st.lists(st.integers(0, 6000), max_size=6))
def test_garbage_between_frames_is_skipped(pieces, tail, cuts):
    stream = b"".join(g + f for g, f in pieces) + tail
    packets, parser = parse_all(stream, cuts)
    assert [p.raw for p in packets] == [f for _, f in pieces]
    assert parser.skipped == sum(len(g) for g, _ in pieces) + len(tail) - parser.pending()


@PROFILE
@given(ids, st.integers(0, 255), params)
def test_instruction_builder_matches_the_spec(servo_id, ins, data):
    frame = P.instruction(servo_id, ins, data)
    assert frame[:2] == b"\xD5\x5D" and frame[2] == servo_id and frame[3] == len(data) + 2
    assert frame[4] == ins and frame[5:-1] == data
    assert frame[-1] == (servo_id + len(data) + 2 + ins + sum(data)) & 0xFF


@settings(max_examples=50, deadline=None)
@given(st.one_of(st.integers(), st.none(), st.text(max_size=3)), params)
def test_builders_refuse_bad_ids_with_value_error(servo_id, data):
    if isinstance(servo_id, int) and 0 <= servo_id <= P.BROADCAST:
        return
    with pytest.raises((ValueError, TypeError)):
        P.instruction(servo_id, P.PING, data)


@pytest.fixture(scope="module", autouse=True)
def short_bus_times():
    """The Bus tests below run on a wire of given bytes: no return delay to wait for."""
    mp = pytest.MonkeyPatch()
    mp.setattr(P, "MAX_RETURN_DELAY_S", 0.001)
    mp.setattr(servobus.identity, "RESET_SETTLE_S", 0.01)
    yield
    mp.undo()


class WireOfBytes:
    """A transport whose wire carries the given chunks, whatever is sent."""

    is_tcp = False  # the serial slack: shorter time-outs

    def __init__(self, chunks):
        self.chunks = list(chunks)

    def write(self, data):
        pass

    def read(self, deadline):
        if self.chunks:
            return self.chunks.pop(0)
        time.sleep(max(0.0, min(deadline - time.monotonic(), 0.002)))
        return b""

    def flush_input(self):
        pass

    def set_baud(self, baud):
        pass

    def close(self):
        pass


def _bus_on(chunks):
    """A Bus (short time-outs) over a WireOfBytes."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(servobus.link, "open_transport", lambda port, baud: WireOfBytes(chunks))
        return Bus("tcp://wire:1", baud=1792000, timeout=0.002)


def _status(servo_id, err, data):
    body = bytes([servo_id, len(data) + 2, err]) + bytes(data)
    return P.HEADER + body + bytes([sum(body) & 0xFF])


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.one_of(
    st.binary(max_size=30),
    st.builds(_status, st.integers(0, 3), st.integers(0, 255), st.binary(max_size=6))),
    max_size=6), st.sampled_from(["ping", "read", "write", "present", "variant", "dump",
                                  "duplicate", "in_update_mode", "set_id", "reset"]))
def test_the_bus_raises_only_its_own_errors_on_any_wire(chunks, call):
    bus = _bus_on(chunks)
    try:
        {"ping": lambda: bus.ping(1), "read": lambda: bus.read(1, "ccw_angle_limit"),
         "write": lambda: bus.write(1, "acceleration", 5),
         "present": lambda: bus.present(1), "variant": lambda: bus.variant(1),
         "dump": lambda: bus.dump(1), "duplicate": lambda: bus.duplicate(1, tries=1),
         "in_update_mode": lambda: bus.in_update_mode(1),
         "set_id": lambda: bus.set_id(1, 2, check_duplicate=False),
         "reset": lambda: bus.reset(1)}[call]()
    except ServoBusError:
        pass


@settings(max_examples=max(10, EXAMPLES // 4), deadline=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(min_size=1, max_size=6000), st.booleans())
def test_update_of_any_bytes_raises_only_its_own_errors(data, check):
    bus = _bus_on([])
    try:
        bus.update(1, data, check=check, retries=0, restart_timeout=0.01,
                   notify=lambda text: None)
    except ServoBusError as e:
        if check:  # arbitrary bytes are refused before anything is sent
            assert isinstance(e, I.ImageError)
