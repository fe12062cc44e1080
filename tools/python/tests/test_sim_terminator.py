"""servo-sim reports each switch of a servo's RS485 terminator (register 20) on stderr as
`servo-sim: ID N terminator on|off` (issue 25: the register was stored and did nothing).
It switches once the answer to its write has left the wire, and at power-up from flash."""

import socket
import time


def packet(servo_id, ins, *params):
    body = [servo_id, len(params) + 2, ins, *params]
    return bytes([0xD5, 0x5D, *body, sum(body) & 0xFF])


def write_terminator(port, servo_id, on):
    with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
        s.sendall(packet(servo_id, 0x03, 20, 1 if on else 0))
        answer = b""
        deadline = time.monotonic() + 3
        while len(answer) < 6 and time.monotonic() < deadline:
            answer += s.recv(64)
    assert answer[:6] == packet(servo_id, 0x00)  # ERR 0, no parameters


def stop_and_read(sim):
    sim.proc.send_signal(15)
    _, err = sim.proc.communicate(timeout=5)
    return [line for line in err.splitlines() if "terminator" in line]


def test_each_switch_is_reported_and_power_up_applies_the_stored_one(sim_factory, tmp_path):
    sim = sim_factory("1:foot", "2:arm", state_dir=tmp_path)
    write_terminator(sim.port, 2, True)
    write_terminator(sim.port, 1, True)
    write_terminator(sim.port, 1, False)
    write_terminator(sim.port, 2, True)  # already on: no switch, no line
    assert stop_and_read(sim) == ["servo-sim: ID 2 terminator on", "servo-sim: ID 1 terminator on",
                                  "servo-sim: ID 1 terminator off"]
    again = sim_factory("1:foot", "2:arm", state_dir=tmp_path)  # a power cycle
    time.sleep(0.2)
    assert stop_and_read(again) == ["servo-sim: ID 2 terminator on"]
