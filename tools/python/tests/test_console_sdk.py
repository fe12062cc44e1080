"""Issue 29's SDK pieces: frames in words, typed hex, the servoctl command of a frame,
READ planning, the host's copy of the planner, configuration files."""

import pytest

from servobus import Bus, RangeError
from servobus import config as C
from servobus import frames as F
from servobus import planner
from servobus import polling as Poll
from servobus import protocol as P


def test_a_frame_is_decoded_into_registers_units_and_err_words():
    write = P.instruction(2, P.WRITE, bytes([30]) + P.u16(900) + P.u16(180))
    d = F.decode_instruction(write, resolution=1)
    assert d["name"] == "WRITE" and d["id"] == 2
    assert d["fields"] == [("goal_position", 900, "90 deg"), ("moving_speed", 180, "18 deg/s")]
    read = P.instruction(2, P.READ, bytes([46, 1]))
    answer = bytes.fromhex("d55d020301") + bytes([0x19, P.checksum(bytes([2, 3, 1, 0x19]))])
    s = F.decode_status(answer, read)
    assert s["summary"] == "present_temperature = 25 (25 C)" and s["err_words"] == [
        "over-temperature (above register 11)"]


def test_every_instruction_and_custom_sub_of_the_table_is_decoded_by_name():
    # Issue 28: the names come from protocol.json (the firmware's table), not a hand list,
    # so an instruction or sub-command added there is named, not shown as a bare code.
    for ins in P.TABLE["instructions"]:
        d = F.decode_instruction(P.instruction(1, ins["code"], bytes(ins["params_min"])))
        assert d["name"] == P.INSTRUCTION_NAMES[ins["code"]]
        assert d["name"].replace("/", " ") == ins["name"].upper().replace("_", " ")
    for sub in P.TABLE["custom_subs"]:
        d = F.decode_instruction(P.instruction(P.BROADCAST, P.CUSTOM, bytes([sub["sub"]])))
        assert sub["name"].replace("_", " ") in d["summary"], (sub, d["summary"])
    assert F.decode_instruction(P.instruction(1, P.START_END, bytes([1])))["name"] == "START/END"


def test_typed_hex_gets_its_checksum_and_a_wrong_one_is_refused():
    assert F.parse_hex("D5 5D 02 04 02 2E 01") == P.instruction(2, P.READ, bytes([46, 1]))
    assert F.parse_hex("02 04 02 2e 01") == P.instruction(2, P.READ, bytes([46, 1]))
    with pytest.raises(RangeError, match="is wrong"):
        F.parse_hex("D5 5D 02 04 02 2E 01 00")
    for bad in ("", "zz", "D5 5D 02 09 02", "D5 5D FF 02 01"):
        with pytest.raises(RangeError):
            F.parse_hex(bad)


def test_a_frame_offers_the_servoctl_command_that_sends_it():
    assert F.servoctl(P.instruction(2, P.WRITE, bytes([5, 40])), "tcp://h:1") == \
        "servoctl --port tcp://h:1 --id 2 set return_delay 40"
    assert F.servoctl(P.instruction(7, P.PING)) == "servoctl --id 7 ping"
    assert F.servoctl(P.instruction(P.BROADCAST, P.ACTION)) is None


def test_picked_registers_are_read_in_as_few_reads_as_the_wire_favours():
    reads = Poll.plan_reads({1: ["present_speed", "present_temperature"], 2: ["model_number",
                                                                             "moving"]})
    assert [(r[0], r[1], r[2]) for r in reads] == [(1, 38, 9), (2, 0, 2), (2, 42, 1)]
    with pytest.raises(RangeError, match="write-only"):
        Poll.plan_reads({1: ["clear_unload"]})
    one = Poll.wire_limit_hz([(1, 36, 11, [])], 9600)
    assert one == pytest.approx(1 / (25 * 10 / 9600 + 0.008))


def test_the_planner_lands_exactly_and_takes_the_time_its_ramps_say():
    prof = planner.trajectory(900, [(1800, 900)], resolution=1)  # 90 deg at 90 deg/s
    assert prof[-1][1] == 1800 and prof[-1][0] == pytest.approx(1.0, abs=0.01)
    ramped = planner.trajectory(900, [(1800, 900)], resolution=1, acc=9, dec=9)
    assert ramped[-1][1] == 1800 and ramped[-1][0] == pytest.approx(2.0, abs=0.02)
    # a change of direction stops at the turning point
    back = planner.trajectory(0, [(300, 100), (100, 100)], resolution=10)
    assert max(p for _, p in back) == 300 and back[-1][1] == 100


def test_configuration_diff_and_check():
    a = {"format": C.FORMAT, "variant": "foot", "settings": {"return_delay": 16, "id": 1}}
    b = {"format": C.FORMAT, "variant": "foot", "settings": {"return_delay": 40, "id": 1}}
    assert C.diff(a, b) == [("return_delay", 16, 40)]
    C.check(a)
    with pytest.raises(RangeError, match="not a setting of the foot"):
        C.check(dict(a, settings={"base_acceleration": 1}))
    with pytest.raises(RangeError, match="out of range"):
        C.check(dict(a, settings={"status_return_level": 3}))


def test_a_restore_goes_only_onto_the_same_variant_within_the_commit_budget(sim_factory):
    sim = sim_factory("1:arm", "2:foot", "3:foot")
    with Bus(sim.url) as bus:
        bus.write(2, {"return_delay": 40})
        bus.write(2, {"temperature_limit": 70})
        doc = C.save(bus, 2)
        with pytest.raises(RangeError, match="same variant"):
            C.restore_plan(bus, 1, doc)
        changes, reasons, runs = C.restore_plan(bus, 3, doc)
        assert changes == {"return_delay": 40, "temperature_limit": 70} and not reasons
        assert len(runs) == 2
        key = bus.budget_key(3)
        while bus.commit_budget.tokens(key) > 1:
            bus.commit_budget.commit(key)
        with pytest.raises(RangeError, match="can commit 1 at once"):
            C.restore_plan(bus, 3, doc)
        bus.commit_budget.restarted(key)
        C.restore(bus, 3, changes)
        assert C.diff(C.save(bus, 3), doc) == [("id", 3, 2)]
