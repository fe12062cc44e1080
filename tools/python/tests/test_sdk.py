"""The SDK end to end against servo-sim."""

import time

import pytest

from conftest import BUS_IDS, wait_until
from servobus import (BROADCAST, VARIANTS, Bus, BusTimeout, ChecksumError, IdTaken,
                      InstructionError, MotionRefused, RangeError, ServoFault,
                      UnknownRegister, register)
from servobus import protocol as P
from servobus.errors import status_error


def test_scan_finds_every_id_of_a_mixed_bus(bus):
    start = time.monotonic()
    found = bus.scan()
    took = time.monotonic() - start
    assert [f.id for f in found] == BUS_IDS
    assert all(f.err == 0 and f.baud == 9600 for f in found)
    assert took < 3.5  # one broadcast PING: 254 slots of 9 bytes at 9600 baud


def test_scan_all_bauds_over_tcp_scans_once_with_a_note(bus):
    found = bus.scan(all_bauds=True)
    assert [f.id for f in found] == BUS_IDS
    assert any("over tcp://" in n for n in bus.scan_notes)


def test_variants_and_defaults_come_from_the_table(bus):
    expect = {1: "arm", 2: "foot", 3: "base", 7: "wrist", 200: "finger"}
    for servo_id, name in expect.items():
        v = bus.variant(servo_id)
        assert v.name == name
        assert bus.read(servo_id, "model_number") == VARIANTS[name].model_number
        assert bus.read(servo_id, "return_delay") == register("return_delay").default[name]
        assert bus.read(servo_id, "ccw_angle_limit") == register("ccw_angle_limit").default[name]


def test_ping(bus):
    assert bus.ping(1) == 0
    assert bus.present(200)
    assert not bus.present(9, timeout=0.1)


def test_time_out_says_what_to_check(bus):
    with pytest.raises(BusTimeout) as e:
        bus.ping(9)
    msg = str(e.value)
    assert "no status packet from ID 9 at 9600 baud" in msg
    assert "wrong ID or baud? try `servoctl scan --all-bauds`" in msg
    assert e.value.servo_id == 9


def test_read_write_by_name_and_address(bus):
    bus.write(1, "acceleration", 50)
    assert bus.read(1, "acceleration") == 50
    assert bus.read(1, 34) == 50
    bus.write(1, 34, 36)
    assert bus.read(1, "acceleration") == 36
    bus.write(2, {"acceleration": 20, "deceleration": 30})
    assert bus.read_many(2, ["acceleration", "deceleration"]) == {
        "acceleration": 20, "deceleration": 30}
    bus.write(2, {"acceleration": 36, "deceleration": 36})


def test_out_of_range_is_refused_before_sending(bus):
    with pytest.raises(RangeError, match=r"return_delay: 300 is out of range 0\.\.255"):
        bus.write(1, "return_delay", 300)
    with pytest.raises(RangeError, match=r"status_return_level: 3 is out of range 0\.\.2"):
        bus.write(1, "status_return_level", 3)
    with pytest.raises(RangeError, match="read-only"):
        bus.write(1, "present_speed", 1)
    with pytest.raises(RangeError, match="does not exist on the arm"):
        bus.write(1, "base_acceleration", 10)
    with pytest.raises(RangeError, match="not contiguous"):
        bus.write(1, {"acceleration": 1, "brake": 0})
    with pytest.raises(UnknownRegister, match="no register named 'nope'"):
        bus.read(1, "nope")
    with pytest.raises(UnknownRegister, match="address 10"):
        bus.read(1, 10)
    assert bus.read(1, "return_delay") == 16


def test_units_and_signs():
    goal, speed, temp = register("goal_position"), register("moving_speed"), \
        register("temperature_limit")
    assert goal.parse("90deg") == 90 and goal.parse("90deg", resolution=1) == 900
    assert speed.parse("-45deg/s") == -45 and speed.encode(-45) == 0x802D
    assert speed.decode(0x802D) == -45
    assert register("present_speed").decode(0xFFFE) == -2
    assert temp.parse("-5C") == -5 and temp.encode(-5) == 0x85
    assert register("return_delay").parse("8ms") == 16
    assert register("unload_conditions").parse("0x22") == 0x22
    assert register("return_delay").parse(" -0") == 0
    with pytest.raises(RangeError, match="not a number"):
        register("return_delay").parse("eight")
    assert register("current_limit").format(30) == "30 (3 A)"
    assert goal.format(900, resolution=1) == "900 (90 deg)"
    with pytest.raises(RangeError, match="unit 'ms' does not fit"):
        goal.parse("5ms")
    with pytest.raises(RangeError, match="out of range"):
        speed.parse("40000")


def test_the_firmware_refuses_what_the_sdk_lets_through(bus):
    with pytest.raises(InstructionError) as e:
        bus.write(1, "base_acceleration", 10, check_variant=False)
    assert e.value.err & P.ERR_INSTRUCTION
    assert "ID 1 refused WRITE base_acceleration=10" in str(e.value)
    assert "instruction error" in str(e.value)
    with pytest.raises(InstructionError, match="CW limit above the CCW limit"):
        bus.write(1, "cw_angle_limit", 400)  # above the CCW limit 360
    with pytest.raises(InstructionError):
        bus.write_raw(1, 0, b"\x01\x02")  # model number is read-only


def test_reg_write_and_action(bus):
    bus.reg_write(1, "acceleration", 40)
    bus.reg_write(2, "acceleration", 41)
    assert bus.read(1, "registered") == 1 and bus.read(1, "acceleration") == 36
    bus.action()  # broadcast: both at once
    assert wait_until(lambda: bus.read(2, "registered") == 0)
    assert bus.read(1, "acceleration") == 40 and bus.read(2, "acceleration") == 41
    with pytest.raises(InstructionError, match="nothing was held"):
        bus.action(1)
    bus.sync_write("acceleration", {1: 36, 2: 36})


def test_sync_write(bus):
    bus.sync_write("deceleration", {1: 11, 2: 12, 7: 17})
    assert wait_until(lambda: bus.read(7, "deceleration") == 17)
    assert [bus.read(i, "deceleration") for i in (1, 2)] == [11, 12]
    bus.sync_write(["acceleration", "deceleration"],
                   {i: {"acceleration": 36, "deceleration": 36} for i in (1, 2, 7)})
    assert wait_until(lambda: bus.read(7, "deceleration") == 36)
    with pytest.raises(RangeError):
        bus.sync_write("deceleration", {1: 256})


def test_dump_reads_the_whole_table(bus):
    rows = dict((r.name, v) for r, v in bus.dump(3))
    assert rows["id"] == 3 and rows["model_number"] == VARIANTS["base"].model_number
    assert rows["acceleration"] is None  # not on the base
    assert rows["clear_unload"] is None  # write-only
    assert rows["base_acceleration"] == 36


def test_set_id_refuses_a_taken_id(bus):
    with pytest.raises(IdTaken, match="ID 2 is already taken"):
        bus.set_id(1, 2)
    assert bus.ping(1) == 0 and bus.variant(2).name == "foot"


def test_set_id_and_back(bus):
    bus.set_id(200, 201)
    with pytest.raises(BusTimeout):
        bus.ping(200)
    assert bus.read(201, "id") == 201
    bus.set_id(201, 200)
    assert bus.ping(200) == 0


def test_motion_instructions_refused_raise_motion_refused(bus):
    bus.trajectory_write(2, [])  # clears the stored trajectory
    with pytest.raises(MotionRefused, match="ID 2 refused TRAJECTORY ACTION") as e:
        bus.trajectory_action(2)
    assert "no trajectory stored" in str(e.value)
    with pytest.raises(MotionRefused, match="START/END"):
        bus.start_end(3, "start")  # the base is always in speed mode


def test_trajectory_write_checks_points(bus):
    with pytest.raises(RangeError, match="speed 0"):
        bus.trajectory_write(2, [(10, 0)])
    with pytest.raises(RangeError, match="do not fit"):
        bus.trajectory_write(2, [(1, 1)] * 85)
    bus.trajectory_write(2, [(10, 20), (30, 40)])
    bus.trajectory_write(2, [(i, 5) for i in range(70)])  # 3-byte form
    bus.trajectory_write(2, [])


def test_custom_move_checks_arguments(bus):
    with pytest.raises(RangeError, match="both acceleration and deceleration"):
        bus.move_relative(2, 10, 30, acc=5)
    with pytest.raises(RangeError, match="out of range"):
        bus.move_absolute(2, 70000, 30)


def test_move_on_the_foot(bus):
    """Position mode end to end: the goal is written and the simulated motor gets there
    (the foot has no photo switches, so no homing is needed)."""
    start = bus.position(2)
    try:
        bus.move(2, 45, speed=180)
        assert bus.read(2, "goal_position") == 45
        ok = wait_until(lambda: abs(bus.position(2) - 45) <= 1 and not bus.read(2, "moving"),
                        timeout=4)
        assert ok, "position %d, moving %d" % (bus.position(2), bus.read(2, "moving"))
    finally:
        bus.move(2, start, speed=180)
        wait_until(lambda: not bus.read(2, "moving"), timeout=4)
        bus.stop(2)


def test_homing_helpers(bus):
    bus.home(7)
    st = bus.homing_status(7)
    assert st.requested == 1 and st.state in (0, 1, 2, 3)
    bus.stop_homing(7)
    assert bus.homing_status(7).requested == 0


def test_err_bits_become_exceptions():
    e = status_error(4, P.ERR_OVER_TEMPERATURE | P.ERR_STALL, "READ 2 bytes from 36",
                     params=b"\x01\x02")
    assert isinstance(e, ServoFault) and e.params == b"\x01\x02"
    assert "over-temperature" in str(e) and "stall" in str(e) and "ID 4" in str(e)
    assert isinstance(status_error(4, P.ERR_CHECKSUM, "WRITE"), ChecksumError)
    assert isinstance(status_error(4, P.ERR_INSTRUCTION | P.ERR_OVER_CURRENT, "WRITE"),
                      InstructionError)
    assert isinstance(status_error(4, P.ERR_INSTRUCTION, "CUSTOM", motion=True),
                      MotionRefused)


def test_checksum_error_answer(bus):
    pkt = bytearray(P.instruction(1, P.READ, b"\x03\x01"))
    pkt[-1] ^= 0xFF
    bus._t.flush_input()
    bus._t.write(bytes(pkt))
    answer = bus.receive(1, bytes(pkt), 6, "READ")
    assert answer.err == P.ERR_CHECKSUM
    with pytest.raises(ChecksumError, match="received a corrupted"):
        bus._check(1, answer.err, "READ", "", b"", False)


def test_parser_resynchronises():
    parser = P.StatusParser()
    good = bytes.fromhex("d5 5d 01 03 01 00 05")
    got = parser.feed(b"\x00\xd5" + good[:4]) + parser.feed(good[4:] + b"\xd5\x5d\x02")
    assert [p.raw for p in got] == [good] and parser.pending() == 3


def test_status_return_level_0_time_out_names_register_16(sim_factory):
    sim = sim_factory("9:foot")
    with Bus(sim.url) as bus:
        bus.write(9, "status_return_level", 0)  # answered at the old level
        assert bus.ping(9) == 0  # PING is always answered
        with pytest.raises(BusTimeout, match=r"status return level \(register 16\)"):
            bus.write(9, "acceleration", 10)


def test_reset_restores_factory_values(sim_factory):
    sim = sim_factory("12:wrist")
    with Bus(sim.url) as bus:
        bus.write(12, "return_delay", 4)
        bus.reset(12)  # answered by ID 12
        assert wait_until(lambda: bus.present(1, timeout=0.2))
        assert bus.read_many(1, ["id", "return_delay"]) == {"id": 1, "return_delay": 16}


def test_broadcast_write_is_not_answered(sim_factory):
    sim = sim_factory("1:foot", "2:foot")
    with Bus(sim.url) as bus:
        bus.write(BROADCAST, "acceleration", 20)
        assert wait_until(lambda: bus.read(2, "acceleration") == 20)
        assert bus.read(1, "acceleration") == 20
