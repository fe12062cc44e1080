"""The adversarial round on Servo Studio, continued (issues 26 and 29): group moves,
restores and confirmations cut short or sent while another tab acts, through a raw client
(and Chromium where the page's words matter). Each test failed before the fix it names."""

import time

from raw import not_sampling, ready, writes_to
from servobus.registers import REGISTERS


def test_a_group_move_cut_short_leaves_no_held_goal_for_a_later_action(tapped):
    # Move together is a REG WRITE to each servo, then one broadcast ACTION. When the
    # second servo does not answer (here: status return level 0; or unplugged, or a STOP
    # between the REG WRITEs and the ACTION) the first one kept its goal held, and the
    # broadcast ACTION of a later group move — of other servos — started it: a move the
    # user saw refused ran minutes later
    t = tapped("2:foot", "7:foot", "8:foot", "9:foot")
    ready(t, 4)
    assert t.api.post("/api/write", {"id": 9, "name": "status_return_level", "value": 0,
                                     "confirm": True})[0] == 200
    status, answer = t.api.post("/api/group", {"goals": {"2": 300, "9": 300},
                                               "speed": 200})
    assert status == 422, answer  # ID 9 does not answer its REG WRITE
    mark = t.tap.mark()
    # ID 2 answers: its held goal is replaced. ID 9 does not: a broadcast ACTION would
    # start it, so the move of 7 and 8 is refused in words, nothing moved ...
    status, answer = t.api.post("/api/group", {"goals": {"7": 10, "8": 10}, "speed": 60})
    assert status == 409 and "ID 9 may still hold the goal" in answer["error"], answer
    time.sleep(0.3)
    assert [raw for _, raw in t.tap.packets(mark) if raw[4] == 0x05] == []  # no ACTION
    # ... while one SYNC WRITE (no ACTION) moves them
    status, answer = t.api.post("/api/group", {"goals": {"7": 10, "8": 10}, "speed": 60,
                                               "how": "sync"})
    assert status == 200, answer
    status, answer = t.api.post("/api/console", {"text": "--id 2 get registered goal_position"})
    assert status == 200 and "goal_position = 300" not in answer["output"], answer["output"]
    # ID 9 answers again: its held goal is replaced before the next ACTION, which then
    # starts 7 and 8 only
    assert t.api.post("/api/console", {"text": "D5 5D 09 04 03 10 02"})[0] == 200
    mark = t.tap.mark()
    status, answer = t.api.post("/api/group", {"goals": {"7": 20, "8": 20}, "speed": 60})
    assert status == 200, answer
    status, answer = t.api.post("/api/console", {"text": "--id 9 get goal_position"})
    assert "goal_position = 300" not in answer["output"], answer["output"]
    assert [raw[2] for _, raw in t.tap.packets(mark) if raw[4] == 0x04] == [9, 7, 8]


def test_stop_between_the_reg_writes_and_the_action_leaves_no_held_goal(tapped):
    # at 9600 baud (rfc2217://) a group move of three feet takes about 0.1 s of REG
    # WRITEs before its ACTION: a STOP in between cut it short and left the first ones
    # holding their goals, started by the next group move's ACTION
    import threading
    t = tapped("2:foot", "7:foot", "8:foot", "9:foot", rfc2217=True)
    ready(t, 4)
    for attempt in range(10):  # until the STOP lands between the REG WRITEs
        mark = t.tap.mark()
        out = []
        th = threading.Thread(target=lambda: out.append(t.api.post(
            "/api/group", {"goals": {"2": 300, "7": 300, "8": 300}, "speed": 200})))
        th.start()
        deadline = time.monotonic() + 5
        while not [r for _, r in t.tap.packets(mark) if r[4] == 0x04] and \
                time.monotonic() < deadline:
            time.sleep(0.002)
        assert t.api.post("/api/stop")[0] == 200
        th.join()
        if out[0][0] == 409:  # cut short: "Stopped by STOP"
            break
    else:
        raise AssertionError("the STOP never landed between the REG WRITEs")
    t.api.wait(lambda st: not st["jobs"], what="STOP's jobs done")
    mark = t.tap.mark()
    status, answer = t.api.post("/api/group", {"goals": {"9": 20, "7": 20}, "speed": 60})
    assert status == 200, answer
    status, answer = t.api.post("/api/console", {"text": "--id 2 get goal_position"})
    assert "goal_position = 300" not in answer["output"], answer["output"]


def test_a_confirmed_status_return_level_0_is_not_answered_as_a_failure(tapped):
    # before: written as confirmed, then read back from a servo that answers only PING
    # now: HTTP 422 "No answer from ID 2 ... power and wiring"
    t = tapped("2:foot")
    ready(t, 1)
    mark = t.tap.mark()
    status, answer = t.api.post("/api/write", {"id": 2, "name": "status_return_level",
                                               "value": 0, "confirm": True})
    assert status == 200 and answer["value"] == 0, answer
    assert [d for _, d in writes_to(t.tap, REGISTERS["status_return_level"].address,
                                    mark)] == [b"\x00"]
    status, answer = t.api.post("/api/write", {"id": 2, "name": "status_return_level",
                                               "value": 2})
    assert status == 200 and answer["value"] == 2, answer


def test_a_restore_cut_short_by_stop_says_what_was_written(sim_factory):
    # before: "Stopped by STOP before it was done: nothing more of it was sent." while
    # return_delay and temperature_limit had been written (seen at 9600 baud, STOP 1.05 s
    # into a restore of five settings): the page promised all or nothing
    import threading
    from servobus import Bus, Interrupted
    from servobus import config as C
    from servobus.studio.words import in_words
    sim = sim_factory("2:foot")
    with Bus(sim.url) as bus:
        before = C.save(bus, 2)
        doc = dict(before, settings=dict(before["settings"], return_delay=20,
                                         temperature_limit=75, heartbeat_enable=0,
                                         rs485_termination=1))
        changes, _, runs = C.restore_plan(bus, 2, doc)
        assert len(runs) >= 3
        bus.stop_event = threading.Event()
        writes = []

        def tap(direction, data, _t):  # STOP pressed while the first WRITE is answered
            if direction == "tx" and data[4] == 0x03:
                writes.append(data)
                bus.stop_event.set()
        bus.tap = tap
        try:
            C.restore(bus, 2, changes)
            raise AssertionError("not cut short")
        except Interrupted as e:
            words = in_words(e)
        bus.tap = None
        bus.stop_event = None
        after = C.save(bus, 2)["settings"]
    written = {k for k in changes if after[k] != before["settings"][k]}
    assert len(writes) == 1 and written and written != set(changes), written
    assert "Stopped by STOP part way" in words, words
    for k in changes:  # each setting is named on the side it is on
        assert ("%s = %s" % (k, changes[k]) in words) == (k in written), (k, words)
        assert k in words


def test_trajectory_points_outside_the_angle_limits_are_said_and_planned_clamped(tapped):
    # before: "Trajectory of 2 points written and running." while the servo clamped
    # point 1 (src/traj.c), and the editor's plan drew it going to 350 deg
    t = tapped("2:foot")
    ready(t, 1)
    assert t.api.post("/api/write", {"id": 2, "name": "ccw_angle_limit",
                                     "value": "300"})[0] == 200
    points = [[350, 180], [100, 180]]
    status, answer = t.api.post("/api/plan", {"points": points, "id": 2})
    assert status == 200 and answer["outside"] == [1], answer
    assert max(p for _, p in answer["profile"]) <= 300, "planned past the limit"
    status, answer = t.api.post("/api/traj", {"points": points, "id": 2})
    assert status == 200 and answer["outside"] == [1], answer
    assert "point 1 (350 deg) is outside its angle limits (0..300 deg)" in answer["note"]
    status, answer = t.api.post("/api/traj", {"points": [[200, 180]], "id": 2})
    assert status == 200 and "note" not in answer, answer


def test_a_file_too_large_is_refused_with_a_sentence(tapped):
    # before: aiohttp's plain-text 413, and the page: "The studio answered HTTP 413
    # Request Entity Too Large without a sentence." (an .elf chosen for the image)
    t = tapped("2:foot")
    ready(t, 1)
    mark = t.tap.mark()
    for path, body, ctype in (
            ("/api/update?id=2&file=servo.elf", b"\x7fELF" + bytes(2 << 20),
             "application/octet-stream"),
            ("/api/config/restore", '{"config": "%s"}' % ("x" * (2 << 20)),
             "application/json")):
        status, answer = t.api.request("POST", path, body, headers={"Content-Type": ctype})
        assert status == 413 and isinstance(answer, dict), (path, status, str(answer)[:80])
        assert "more than the studio takes" in answer["error"] and not answer["sent"]
    time.sleep(0.3)
    assert not_sampling(t.tap, mark) == []


def test_a_servo_that_stops_answering_shows_no_stale_live_values(tapped, page):
    # before: the studio knew (state.sample_error) but the page never showed it: the
    # selected servo's position, "moving", its health and the plot's "28 Hz" stayed as
    # if live; the dashboard's row kept its last position next to the error
    t = tapped("2:foot", "7:foot")
    ready(t, 2)
    p = page(t.studio.url)
    p.wait_scanned(2)
    p.select(7)
    p.wait(lambda: p.text("ro-pos").endswith("deg"), what="live values of ID 7")
    p.panel("dash")
    p.wait(lambda: p.all("#dash-table tr[data-id='7'] .d-position") and p.by(
        "#dash-table tr[data-id='7'] .d-position").text.endswith("deg"), what="the row")
    status, answer = t.api.post("/api/write", {"id": 7, "name": "status_return_level",
                                               "value": 0, "confirm": True})
    assert status == 200, answer  # ID 7 answers nothing but PING from now on
    p.wait(lambda: "Live values of ID 7 stopped" in p.message(), what="the page saying so")
    assert "status return level" in p.message()
    assert p.text("ro-pos") == "\u2013" and p.text("moving") == "\u2013"
    p.wait(lambda: p.by("#dash-table tr[data-id='7'] .d-position").text == "\u2013",
           what="the dashboard row without its stale position")
    assert "level" in p.by("#dash-table tr[data-id='7'] .d-err").text
    # it answers again: the values come back
    assert t.api.post("/api/console", {"text": "D5 5D 07 04 03 10 02"})[0] == 200
    p.wait(lambda: p.text("ro-pos").endswith("deg"), what="live values again")


def test_a_new_angle_resolution_is_used_for_the_next_move_at_once(tapped):
    # before: after angle_resolution 5 (0.5 deg a unit), Move together to 100 deg sent
    # 100 units, and the foot went to 50 deg (the studio's cached resolution was 10
    # until the dashboard's slow READ or a select caught up)
    t = tapped("2:foot", "7:foot")
    ready(t, 2)
    assert t.api.post("/api/select", {"id": 7})[0] == 200
    for sid in (2, 7):  # no stop 500 ms after the last packet: the goals stay to be read
        assert t.api.post("/api/write", {"id": sid, "name": "heartbeat_enable",
                                         "value": 0})[0] == 200

    def goal(sid):
        status, answer = t.api.post("/api/console", {"text": "--id %d get goal_position"
                                                             % sid})
        return answer["output"].strip()
    assert t.api.post("/api/write", {"id": 2, "name": "angle_resolution",
                                     "value": 5})[0] == 200  # the control table
    assert t.api.post("/api/console", {"text": "--id 7 set angle_resolution 5"})[0] \
        == 200  # the console (of the selected servo)
    status, answer = t.api.post("/api/group", {"goals": {"2": 100, "7": 80},
                                               "speed": 30})
    assert status == 200, answer
    goals = goal(2), goal(7)
    assert goals == ("goal_position = 200 (100 deg)", "goal_position = 160 (80 deg)"), goals
    status, answer = t.api.post("/api/move", {"goal": 45, "speed": 30, "acc": 36,
                                              "dec": 36})  # the selected one, at once
    assert status == 200 and goal(7) == "goal_position = 90 (45 deg)", goal(7)
    # a hex WRITE of register 13 in the console too
    assert t.api.post("/api/console", {"text": "D5 5D 02 04 03 0D 0A"})[0] == 200
    status, answer = t.api.post("/api/group", {"goals": {"2": 30, "7": 30}, "speed": 30})
    assert status == 200 and goal(2) == "goal_position = 30 (30 deg)", goal(2)
    # a move that names a servo other than the selected one uses that servo's
    # resolution (before: the selected one's, 0.5 deg: 20 deg became 40)
    status, answer = t.api.post("/api/move", {"goal": 20, "speed": 30, "acc": 36,
                                              "dec": 36, "id": 2})
    assert status == 200 and goal(2) == "goal_position = 20 (20 deg)", goal(2)


def test_a_confirmation_goes_to_the_servo_it_asked_about(tapped, page):
    # Two tabs share the selection. Tab A asks "temperature_limit -1: ID 2 would unload
    # at once, write it anyway?"; meanwhile another tab selects ID 7; A's user says yes.
    # Before: the confirmed write went to ID 7 (the selected servo at that moment), and
    # so did a factory reset confirmed for ID 2
    t = tapped("2:foot", "7:foot")
    ready(t, 2)
    p = page(t.studio.url)
    p.wait_scanned(2)
    p.select(2)
    p.panel("table")
    box = p.by("#in-temperature_limit")
    box.clear()
    box.send_keys("-1")
    p.click("set-temperature_limit")
    p.wait(lambda: p.by("#confirm").is_displayed(), what="the confirmation")
    assert "ID 2" in p.text("confirm-text")
    assert t.api.post("/api/select", {"id": 7})[0] == 200  # "another tab"
    mark = t.tap.mark()
    p.click("confirm-yes")
    p.wait(lambda: writes_to(t.tap, REGISTERS["temperature_limit"].address, mark),
           what="the confirmed write")
    assert [raw[2] for _, raw in t.tap.packets(mark) if raw[4] == 0x03] == [2]
    assert t.api.post("/api/write", {"id": 2, "name": "temperature_limit",
                                     "value": "80"})[0] == 200
    # the factory reset's own dialog
    p.select(2)
    p.panel("ident")
    p.click("reset-go")
    p.wait(lambda: p.by("#confirm").is_displayed(), what="the reset dialog")
    assert t.api.post("/api/select", {"id": 7})[0] == 200
    mark = t.tap.mark()
    p.click("confirm-yes")
    p.wait(lambda: [r for _, r in t.tap.packets(mark) if r[4] == 0x06], what="the RESET")
    assert [raw[2] for _, raw in t.tap.packets(mark) if raw[4] == 0x06] == [2]


def test_one_serial_adapter_under_two_names_is_one_bus(studio_factory, tmp_path):
    # a pseudo-terminal stands for a USB adapter, a symlink for its /dev/serial/by-id/
    # name: before, the second studio took another lock file, opened the same device,
    # and both talked on one wire
    import os
    from servobus.studio.process import run_studio
    master, slave = os.openpty()
    try:
        device = os.ttyname(slave)
        alias = tmp_path / "usb-FTDI_adapter-if00-port0"
        alias.symlink_to(device)
        first = studio_factory(device, "--baud", "115200")
        assert first.token
        rc, out, err = run_studio("--port", str(alias), "--listen", "127.0.0.1:0",
                                  timeout=20)
        assert rc == 1 and "is in use" in err and "Servo Studio" in err, (rc, out, err)
    finally:
        os.close(master)
        os.close(slave)
