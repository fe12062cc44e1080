"""Issue 29 in headless Chromium against servo-sim: the wire console, the plot of any
register, all servos at once, the trajectory editor and configuration files. What the
console and the plot show is checked against the frames on the wire, as the tap in
front of servo-sim saw them (tests/wire.py), not against the studio's own account."""

import json
import time

from servobus import protocol as P

SERVOS = ("1:foot", "2:foot", "3:base")


def opened(tapped, page, panel, select=2):
    t = tapped(*SERVOS)
    p = page(t.studio.url)
    p.wait_scanned(3)
    if select is not None:
        p.select(select)
    p.panel(panel)
    return t, p


def typed(p, element_id, text):
    box = p.by("#" + element_id)
    box.clear()
    box.send_keys(text)


def frames(p):
    return p.d.execute_script("return window.studio.expert.frames")


def rows(p):
    """The console table's rows as the page shows them: [[cell text, ...], ...]."""
    return p.d.execute_script(
        "return [...document.querySelectorAll('#con-table tbody tr')].map("
        "(r) => [...r.cells].map((c) => c.textContent))")


def send(p, text):
    typed(p, "con-entry", text)
    before = p.text("con-answer")
    p.click("con-send")
    return p.wait(lambda: p.text("con-answer") != before and p.text("con-answer"),
                  what="the console's answer to %r" % text)


def test_the_console_shows_every_frame_on_the_wire_decoded(tapped, page):
    t, p = opened(tapped, page, "console")
    mark = t.tap.mark()
    answer = send(p, "D5 5D 02 04 02 2E 01")  # READ present_temperature, no checksum
    assert "present_temperature = 25 (25 C)" in answer and "answers #" in answer, answer
    sent = bytes.fromhex("d55d0204022e01") + bytes([P.checksum(bytes.fromhex("0204022e01"))])
    assert sent in [raw for _, raw in t.tap.packets(mark)]  # the checksum filled in
    # every frame the console shows is a frame on the wire, in the same order, both ways
    time.sleep(0.5)
    shown = frames(p)
    tx = [bytes.fromhex(f["hex"]) for f in shown if f["dir"] == "tx"]
    wire = [raw for _, raw in t.tap.packets()]
    assert len(tx) > 20 and tx == wire[:len(tx)]
    rx = [bytes.fromhex(f["hex"]) for f in shown if f["dir"] == "rx" and f["hex"]]
    assert len(rx) > 20 and rx == t.tap.answers()[:len(rx)]
    read = next(f for f in reversed(shown) if f["dir"] == "tx" and f["hex"] == sent.hex(" "))
    reply = next(f for f in shown if f.get("answers") == read["n"])
    assert reply["summary"] == "present_temperature = 25 (25 C)"
    assert reply["err_words"] == ["no error"]
    # an instruction error in words, and the errors-only filter
    answer = send(p, "D5 5D 02 02 05")  # ACTION with nothing held: refused by the servo
    assert "instruction error" in answer, answer
    p.by("#con-err").click()
    p.wait(lambda: rows(p) and all("instruction error" in r[6] for r in rows(p)),
           what="only the error rows")
    p.by("#con-err").click()
    typed(p, "con-id", "2")
    p.by("#con-ins option[value='READ']").click()
    p.wait(lambda: rows(p) and all(r[3] == "2" and r[4] == "READ" for r in rows(p)),
           what="READs of ID 2 only")
    # copy as servoctl, and the same command typed back sends the same frame
    row = p.by("#con-table tbody tr[data-n='%d']" % read["n"])
    row.find_element("css selector", "button.copy").click()
    cmd = p.d.execute_script("return window.studio.expert.copied")
    assert cmd == "servoctl --port %s --id 2 get present_temperature" % t.tap.url, cmd
    mark = t.tap.mark()
    answer = send(p, cmd.replace("--port %s " % t.tap.url, ""))
    assert answer.startswith("present_temperature = 25 (25 C)"), answer
    # servoctl get reads the whole table in one READ (two servos on one ID refused)
    assert bytes.fromhex("d55d02040200323a") in [raw for _, raw in t.tap.packets(mark)]


def test_the_console_pauses_exports_and_asks_before_a_lock_out(tapped, page):
    t, p = opened(tapped, page, "console")
    p.click("con-pause")
    time.sleep(0.3)
    count = p.text("con-info")
    time.sleep(0.6)
    assert p.text("con-info") == count and "paused" in count
    p.click("con-pause")
    p.wait(lambda: p.text("con-info") != count, what="the console running again")
    csv, hexf = p.download(["con-csv", "con-hex"], ["wire-*.csv", "wire-*.hex.txt"])
    rows = p.lines(csv)
    assert rows[0] == "n,t_s,direction,id,instruction,decoded,err,answers,hex,servoctl"
    lines = p.lines(hexf)
    wire = {raw.hex(" ") for _, raw in t.tap.packets()}
    sent = [ln.split(" ", 2)[2] for ln in lines if " > " in ln]
    assert sent and all(h in wire for h in sent)
    # a lock-out setting typed in the console asks first; Cancel sends nothing
    mark = t.tap.mark()
    typed(p, "con-entry", "--id 2 set status_return_level 0")
    p.click("con-send")
    p.wait(lambda: p.by("#confirm").is_displayed(), what="the confirmation")
    assert "status_return_level 0" in p.text("confirm-text")
    p.click("confirm-no")
    time.sleep(0.3)
    assert not [raw for _, raw in t.tap.packets(mark) if raw[4] == P.WRITE]
    # refused before sending, in words: a wrong checksum, --force, an update frame
    for text, words in (("D5 5D 02 04 02 2E 01 00", "0x00 is wrong: this frame's is 0x37"),
                        ("--id 2 set status_return_level 0 --force", "no --force"),
                        ("D5 5D 02 03 FF FC", "Firmware panel")):
        typed(p, "con-entry", text)
        p.click("con-send")
        p.wait(lambda: words in p.text("con-answer"), what="refused: " + words)
    assert not [raw for _, raw in t.tap.packets(mark) if raw[4] != P.READ]


def test_any_register_is_plotted_at_the_rate_the_wire_allows(tapped, page):
    t, p = opened(tapped, page, "scope")
    for sid in (1, 2):
        p.by(".scope-id[value='%d']" % sid).click()
    p.by("#scope-reg option[value='moving_speed']").click()
    p.click("scope-add")
    p.by("#scope-reg option[value='present_speed']").click()
    p.click("scope-add")
    p.wait(lambda: len(p.all("#scope-traces li")) == 4, what="four traces")
    mark = t.tap.mark()
    info = p.wait(lambda: "samples" in p.text("scope-info") and
                  int(p.text("scope-info").split()[0]) > 30 and p.text("scope-info"),
                  what="register samples")
    # one READ per servo covers both registers (32-39), every servo read as often
    reads = [raw for _, raw in t.tap.packets(mark) if raw[4] == P.READ and raw[5:7] ==
             bytes([32, 8])]
    per = {sid: sum(1 for r in reads if r[2] == sid) for sid in (1, 2)}
    assert per[1] > 10 and abs(per[1] - per[2]) <= 1, per
    import re
    m = re.search(r"([\d.]+) Hz achieved · wire limit ([\d.]+) Hz for 2 READs", info)
    assert m, info
    hz, wire_hz = float(m.group(1)), float(m.group(2))
    assert 5 <= hz <= wire_hz, info
    p.panel("motion")
    typed(p, "mv-goal", "300")
    typed(p, "mv-speed", "120")
    p.click("mv-go")
    p.panel("scope")
    p.wait(lambda: max(v for v in p.d.execute_script(
        "return window.studio.expert.scope.v['2.moving_speed']") if v is not None) == 120,
        what="ID 2's moving speed plotted at 120 deg/s")
    p.wait(lambda: max(v for v in p.d.execute_script(
        "return window.studio.expert.scope.v['2.present_speed']") if v is not None) > 60,
        what="ID 2's speed plotted")
    from selenium.webdriver.common.action_chains import ActionChains
    ActionChains(p.d).move_to_element(p.by("#scope-chart")).perform()
    p.wait(lambda: p.text("scope-cursor").startswith("t = "), what="the cursor read-out")
    p.click("scope-pause")
    frozen = len(p.d.execute_script("return window.studio.expert.scope.t"))
    time.sleep(0.5)
    assert len(p.d.execute_script("return window.studio.expert.scope.t")) == frozen
    csv, png = p.download(["scope-csv", "scope-png"], ["registers-*.csv", "registers-*.png"])
    rows = p.lines(csv)
    assert rows[0] == ("t_s,id1_moving_speed_degs,id2_moving_speed_degs,"
                       "id1_present_speed_degs,id2_present_speed_degs")
    assert len(rows) == frozen + 1
    assert p.wait(lambda: png.read_bytes()[:4] == b"\x89PNG", what="a PNG")


def test_all_servos_live_move_together_and_stop_together(tapped, page):
    t, p = opened(tapped, page, "dash", select=None)
    p.wait(lambda: len(p.all("#dash-table tbody tr")) == 3 and
           "25 °C" in p.by("#dash-table tbody tr[data-id='3']").text, what="three rows")
    assert "speed" in p.by("#dash-table tr[data-id='3'] .d-mode").text
    assert "position" in p.by("#dash-table tr[data-id='1'] .d-mode").text
    assert "Hz achieved" in p.text("dash-info")
    for sid, goal in ((1, "100"), (2, "150")):
        p.by(".dash-pick[value='%d']" % sid).click()
        typed(p, "dash-goal-%d" % sid, goal)
    mark = t.tap.mark()
    p.click("dash-go")
    p.wait(lambda: all(abs(float(p.by("#dash-table tr[data-id='%d'] .d-position" % s)
                                 .text.split()[0]) - g) <= 1 for s, g in ((1, 100), (2, 150))),
           timeout=10, what="both at their goals")
    acts = [raw for _, raw in t.tap.packets(mark) if raw[4] in (P.REG_WRITE, P.ACTION)]
    assert [(r[2], r[4]) for r in acts] == [(1, P.REG_WRITE), (2, P.REG_WRITE),
                                           (P.BROADCAST, P.ACTION)]
    # one SYNC WRITE, a long move, then STOP stops them both
    p.by("#dash-how option[value='sync']").click()
    typed(p, "dash-speed", "20")
    for sid, goal in ((1, "300"), (2, "10")):
        typed(p, "dash-goal-%d" % sid, goal)
    mark = t.tap.mark()
    p.click("dash-go")
    p.wait(lambda: all(p.by("#dash-table tr[data-id='%d'] .d-moving" % s).text == "moving"
                       for s in (1, 2)), what="both moving")
    assert [r[4] for _, r in t.tap.packets(mark) if r[4] == P.SYNC_WRITE] == [P.SYNC_WRITE]
    p.click("stop")
    p.wait(lambda: all(p.by("#dash-table tr[data-id='%d'] .d-moving" % s).text == "still"
                       for s in (1, 2)), timeout=3, what="both stopped")
    # the base has no goal: refused in words, nothing sent
    p.by(".dash-pick[value='3']").click()
    typed(p, "dash-goal-3", "90")
    p.click("dash-go")
    p.wait(lambda: "speed mode" in p.message(), what="the base refused")


def test_the_trajectory_editor_plans_as_the_firmware_moves(tapped, page):
    t, p = opened(tapped, page, "trajed")
    plan = p.wait(lambda: p.d.execute_script("return window.studio.expert.te.plan"),
                  what="the planned profile")
    assert plan[-1][1] == 90  # it ends on the last point
    n0 = len(p.d.execute_script("return window.studio.expert.te.points"))
    from selenium.webdriver.common.action_chains import ActionChains
    chart = p.by("#te-chart")
    ActionChains(p.d).move_to_element_with_offset(chart, -chart.size["width"] // 4,
                                                         -chart.size["height"] // 3).click() \
        .perform()
    p.wait(lambda: len(p.d.execute_script("return window.studio.expert.te.points")) ==
           n0 + 1, what="a point added by a click")
    p.click("te-clear")
    typed(p, "te-speed", "90")
    p.d.execute_script("window.studio.expert.te.points = [[150, 90], [60, 120]];")
    p.d.execute_script("plan();")
    p.wait(lambda: p.d.execute_script("return window.studio.expert.te.plan.slice(-1)[0][1]")
           == 60, what="the plan of two points")
    mark = t.tap.mark()
    p.click("te-run")
    plan = p.d.execute_script("return window.studio.expert.te.plan")
    p.wait(lambda: len(p.d.execute_script("return window.studio.expert.te.measured")) > 20
           and p.d.execute_script("return window.studio.expert.te.runAt") is None,
           timeout=15, what="the measured response")
    traj = [raw for _, raw in t.tap.packets(mark) if raw[4] == P.TRAJ_WRITE]
    assert traj and traj[0][5:-1] == bytes([2]) + P.u16(150) + P.u16(90) + P.u16(60) + \
        P.u16(120)
    measured = p.d.execute_script("return window.studio.expert.te.measured")
    assert abs(measured[-1][1] - 60) <= 1
    # the measured position follows the plan (the sample time is one READ late at most)
    worst = max(min(abs(pos - q) for tq, q in plan if abs(tq - tm) < 0.15)
                for tm, pos in measured if tm <= plan[-1][0])
    assert worst < 8, worst


def test_configuration_files_save_restore_and_diff(tapped, page, tmp_path):
    t, p = opened(tapped, page, "config")
    status, _ = t.api.post("/api/write", {"id": 2, "name": "return_delay", "value": 40})
    assert status == 200
    f, = p.download(["cfg-save"], ["servo-2-foot*.json"])
    doc = p.wait(lambda: json.loads(f.read_text()), what="the JSON")
    assert (doc["variant"], doc["firmware_version"], doc["settings"]["return_delay"]) == \
        ("foot", 1, 40)
    p.select(1)
    p.panel("config")
    p.by("#cfg-file").send_keys(str(f))
    mark = t.tap.mark()
    p.click("cfg-restore")
    p.wait(lambda: "Restored 1 settings" in p.text("cfg-result"), what="the restore")
    writes = [raw for _, raw in t.tap.packets(mark) if raw[4] == P.WRITE]
    assert [(w[2], w[5], w[6]) for w in writes] == [(1, 5, 40)]  # not the ID, not the baud
    p.by("#cfg-a option[value='1']").click()
    p.by("#cfg-b option[value='2']").click()
    p.click("cfg-diff")
    p.wait(lambda: [r.text for r in p.all("#cfg-table tbody tr")] == ["id 1 2"],
           what="only the ID differs")
    # a file that would lock the servo out asks first; Cancel writes nothing
    doc["settings"]["status_return_level"] = 0
    bad = tmp_path / "level0.json"
    bad.write_text(json.dumps(doc))
    p.by("#cfg-file").send_keys(str(bad))
    mark = t.tap.mark()
    p.click("cfg-restore")
    p.wait(lambda: p.by("#confirm").is_displayed(), what="the confirmation")
    p.click("confirm-no")
    time.sleep(0.3)
    assert not [raw for _, raw in t.tap.packets(mark) if raw[4] == P.WRITE]
