"""Servo Studio in a real headless Chromium against servo-sim: what a user does."""

import re
import time

from servobus import VARIANTS
from servobus import image as I
from servobus.studio.process import run_studio

SERVOS = ("1:arm", "2:foot", "3:base")


def position(page):
    """Present position (deg) in the Motion panel's live readout."""
    m = re.fullmatch(r"(-?[\d.]+) deg", page.text("ro-pos"))
    assert m, page.text("ro-pos")
    return float(m.group(1))


def plot_info(page):
    """(samples, Hz, position) from the line above the live plot."""
    text = page.d.find_element("id", "plot-info").get_attribute("textContent")
    m = re.search(r"(\d+) samples · ([\d.]+) Hz · position (-?[\d.]+) deg", text)
    assert m, text
    return int(m.group(1)), float(m.group(2)), float(m.group(3))


def on_the_foot(sim, studio_factory, page, panel):
    """The studio on sim, the page open and scanned, the foot (ID 2) selected, panel
    shown."""
    p = page(studio_factory(sim.url).url)
    p.wait_scanned(3)
    p.select(2)
    p.panel(panel)
    return p


def test_the_scan_at_start_finds_the_servos_and_a_second_tab_shares_the_state(
        sim_factory, studio_factory, page):
    sim = sim_factory(*SERVOS)
    studio = studio_factory(sim.url)
    p = page(studio.url)
    rows = p.wait_scanned(3)  # no click: the studio scanned when it started
    assert [r[:5] for r in rows] == [
        ["1", "arm", "0x%04X" % VARIANTS["arm"].model_number, "1", "9600"],
        ["2", "foot", "0x%04X" % VARIANTS["foot"].model_number, "1", "9600"],
        ["3", "base", "0x%04X" % VARIANTS["base"].model_number, "1", "115200"]]
    assert all(r[5] == "no error" for r in rows)
    assert "3 servos found at 9600 baud" in p.text("scan-message")
    p.select(2)
    first = p.d.current_window_handle
    p.d.switch_to.new_window("tab")
    try:
        p.d.get(studio.url)
        p.wait(lambda: "ID 2 (foot)" in p.text("table-who"), what="the second tab "
               "showing the servo the first one selected")
        assert len(p.scan_rows()) == 3
    finally:
        p.d.close()
        p.d.switch_to.window(first)
    # A second process on the same bus is told the port is in use.
    rc, out, err = run_studio("--port", sim.url, "--listen", "127.0.0.1:0")
    assert rc == 1 and "in use" in err and "Servo Studio (process" in err, err


def test_a_register_edit_shows_and_survives_a_restart_of_the_servo(
        sim_factory, studio_factory, page, tmp_path):
    sim = sim_factory(*SERVOS, state_dir=tmp_path)
    p = on_the_foot(sim, studio_factory, page, "table")
    p.wait(lambda: p.value("return_delay") == "16 (8 ms)", what="the factory return delay")
    sent = p.commands()
    p.by("#in-return_delay").send_keys("40")
    p.click("set-return_delay")
    p.wait(lambda: p.value("return_delay") == "40 (20 ms)", what="the new value shown")
    assert p.commands() == sent + 1
    sim.stop()  # the servos lose power; their flash is in tmp_path
    sim = sim_factory(*SERVOS, state_dir=tmp_path, port=sim.port)
    p.panel("log")
    p.wait(lambda: "reconnected" in p.text("log-list"), timeout=20,
           what="the studio reconnecting to the restarted servo-sim")
    p.panel("table")
    p.d.execute_script("document.getElementById('val-return_delay').textContent = '?'")
    p.wait(lambda: p.value("return_delay") == "40 (20 ms)",
           what="the value read again after the restart")


def test_a_move_completes_and_the_plot_updates(sim_factory, studio_factory, page):
    p = on_the_foot(sim_factory(*SERVOS), studio_factory, page, "plot")
    samples0, _, pos0 = p.wait(lambda: plot_info(p)[0] > 5 and plot_info(p),
                               what="live samples")
    assert abs(pos0 - 200) > 50  # premise: the goal is far from where it is
    p.panel("motion")
    for field, value in (("mv-goal", "200"), ("mv-speed", "180")):
        box = p.by("#" + field)
        box.clear()
        box.send_keys(value)
    p.click("mv-go")
    p.wait(lambda: p.text("moving") == "still" and abs(position(p) - 200) <= 1,
           timeout=10, what="the move completing at 200 deg")
    p.panel("plot")
    samples1, hz, pos1 = p.wait(lambda: plot_info(p)[0] > samples0 and plot_info(p),
                                what="the plot updating")
    assert abs(pos1 - 200) <= 1
    assert hz >= 20, "live samples at %.1f Hz" % hz
    traced = p.d.execute_script(
        "return window.studio.chart.data.datasets[0].data.map(function (p) { return p.y; })")
    assert max(traced) >= 199 and min(traced) <= pos0 + 1  # the whole move is drawn

    p.click("plot-pause")
    frozen = p.wait(lambda: "paused" in p.text("plot-info") and plot_info(p)[0],
                    what="the plot paused")
    time.sleep(0.5)
    assert plot_info(p)[0] == frozen and p.text("plot-pause") == "Resume"
    csv, png = p.download(["plot-csv", "plot-png"], ["servo-2-*.csv", "servo-2-*.png"])
    rows = p.lines(csv)
    assert rows[0] == "t_s,position_deg,goal_deg,speed_deg_s,temperature_c,load"
    assert len(rows) == frozen + 1
    assert abs(float(rows[-1].split(",")[1]) - 200) <= 1
    assert p.wait(lambda: png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", what="a PNG")
    p.click("plot-pause")
    p.wait(lambda: plot_info(p)[0] > frozen, what="the plot running again")


def test_stop_stops_a_long_move(sim_factory, studio_factory, page):
    p = on_the_foot(sim_factory(*SERVOS), studio_factory, page, "motion")
    for field, value in (("mv-goal", "350"), ("mv-speed", "20")):
        box = p.by("#" + field)
        box.clear()
        box.send_keys(value)
    p.click("mv-go")
    p.wait(lambda: p.text("moving") == "moving" and position(p) > 5,
           what="the long move under way")
    p.click("stop")  # in the header: in view whatever the panel
    p.wait(lambda: p.text("moving") == "still", timeout=2, what="the servo stopping")
    stopped = position(p)
    time.sleep(1.0)
    assert abs(position(p) - stopped) <= 1 and stopped < 300, (stopped, position(p))
    p.panel("log")
    assert "STOP: moving speed 0 to every servo" in p.text("log-list")
    # Speed mode on the foot in position mode would only set a cruise speed: said so.
    sent = p.commands()
    p.panel("motion")
    p.click("sp-go")
    p.wait(lambda: "is in position mode" in p.message(), what="the speed-mode refusal")
    assert p.commands() == sent and p.text("moving") == "still"


def test_a_bad_value_is_refused_with_a_message_and_nothing_is_sent(
        sim_factory, studio_factory, page):
    p = on_the_foot(sim_factory(*SERVOS), studio_factory, page, "table")
    p.wait(lambda: p.value("return_delay") == "16 (8 ms)", what="the factory value")
    sent = p.commands()
    # the SDK's validator words it, as for servoctl; 900ms is converted first
    for text, words in (("300", "return_delay: 300 is out of range 0..255"),
                        ("abc", "return_delay: 'abc' is not a number"),
                        ("7.9", "return_delay: 7.9 is not a whole number"),
                        ("", "return_delay is empty"),
                        ("900ms", "1800 is out of range 0..255")):
        box = p.by("#in-return_delay")
        box.clear()
        box.send_keys(text)
        p.click("set-return_delay")
        p.wait(lambda: words in p.text("msg-return_delay"), what="the message for " + text)
        assert words in p.message()
    time.sleep(1.5)  # a table refresh later
    assert p.value("return_delay") == "16 (8 ms)"
    assert p.commands() == sent


def test_a_firmware_update_reaches_100_percent_and_the_new_version_shows(
        sim_factory, studio_factory, page, tmp_path):
    image = tmp_path / "foot-v7.bin"
    # 4 blocks: servo-sim paces them at the foot's 9600 baud, 1.1 s each
    image.write_bytes(I.build(4096, version=7, model=VARIANTS["foot"].model_number))
    p = on_the_foot(sim_factory(*SERVOS), studio_factory, page, "firmware")
    assert p.text("fw-now") == "1"
    p.by("#fw-file").send_keys(str(image))
    p.wait(lambda: "4096 bytes, model 0x%04X (foot), version 7" % VARIANTS["foot"]
           .model_number in p.text("fw-info"), what="what the file says it is")
    p.click("fw-go")
    p.wait(lambda: p.text("fw-after") == "7", timeout=60, what="the new version")
    assert p.text("fw-pct") == "100 %" and p.by("#fw-bar").get_attribute("value") == "100"
    assert p.text("fw-before") == "1"
    assert "4/4 blocks, 4096/4096 bytes" in p.text("fw-text")
    assert p.text("fw-now") == "7"
    p.panel("scan")
    assert p.scan_rows()[1][:4] == ["2", "foot", "0x%04X" % VARIANTS["foot"].model_number,
                                    "7"]


def test_another_program_on_the_bus_means_port_in_use(sim_factory):
    from servobus import Bus
    sim = sim_factory(*SERVOS)
    with Bus(sim.url) as other:
        assert other.ping(2) == 0  # premise: that program holds servo-sim's client slot
        rc, out, err = run_studio("--port", sim.url, "--listen", "127.0.0.1:0")
    assert rc == 1 and "is in use: another program is connected to it" in err, err


APP_SLOT = 4 * 1024  # the application slot's offset in a --state-dir flash file


def test_a_servo_waiting_in_update_mode_is_recovered(
        sim_factory, studio_factory, page, tmp_path):
    state = tmp_path / "state"
    sim_factory(*SERVOS, state_dir=state).stop()
    flash = state / "servo-2-foot.flash"
    data = bytearray(flash.read_bytes())
    data[APP_SLOT + 5000] ^= 0xFF  # a damaged application: the bootloader stays in charge
    flash.write_bytes(data)
    sim = sim_factory(*SERVOS, state_dir=state)
    image = tmp_path / "foot-v4.bin"
    image.write_bytes(I.build(3000, version=4, model=VARIANTS["foot"].model_number))
    studio = studio_factory(sim.url)
    p = page(studio.url)
    rows = p.wait_scanned(2)
    assert [r[0] for r in rows] == ["1", "3"]  # premise: the foot does not answer a scan
    p.panel("firmware")
    box = p.by("#rc-id")
    box.clear()
    box.send_keys("2")
    p.by("#rc-file").send_keys(str(image))
    p.click("rc-go")
    p.wait(lambda: p.text("fw-after") == "4", timeout=60, what="the recovered version")
    assert p.text("fw-before") == "none (update mode)"
    assert "bootloader" in p.text("fw-note") and p.text("fw-pct") == "100 %"
    p.panel("scan")
    p.click("scan-again")
    rows = p.wait_scanned(3)
    assert rows[1][:4] == ["2", "foot", "0x%04X" % VARIANTS["foot"].model_number, "4"]


def test_a_bus_without_servos_is_said_in_words(studio_factory, page):
    import socket
    import threading
    # A "bus" nobody answers on: a TCP port that takes the bytes and never replies (an
    # empty servo-sim still has its default arm).
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    conns = []

    def swallow():
        conn, _ = server.accept()
        conns.append(conn)
        while conn.recv(4096):
            pass
    threading.Thread(target=swallow, daemon=True).start()
    try:
        p = page(studio_factory("tcp://127.0.0.1:%d" % server.getsockname()[1]).url)
        p.wait(lambda: "No servo answered at 9600 baud" in p.text("scan-message"),
               what="the empty scan in words")
        assert p.scan_rows() == [] and "check power and wiring" in p.text("scan-message")
        p.panel("motion")
        p.click("mv-go")
        p.wait(lambda: "No servo selected" in p.message(), what="the refusal")
    finally:
        server.close()


def test_homing_shows_its_live_status_then_a_trajectory_runs(
        sim_factory, studio_factory, page):
    sim = sim_factory(*SERVOS)
    p = page(studio_factory(sim.url).url)
    p.wait_scanned(3)
    p.select(1)  # the arm: photo switches, moves only once homed
    p.panel("motion")
    p.wait(lambda: p.text("ro-homing") == "never run", what="the arm never homed")
    p.click("home-go")
    p.wait(lambda: p.text("home-status") == "running", what="homing running")
    p.wait(lambda: p.text("home-status") == "done", timeout=60, what="homing done")
    seen = set()
    p.click("traj-run")  # the table's default points: 90, 180, then 120 deg
    p.wait(lambda: seen.add(round(position(p))) or (
        p.text("moving") == "still" and abs(position(p) - 120) <= 1 and min(seen) <= 95),
        timeout=45, what="the trajectory through 90 deg ending at 120 deg")
    p.panel("log")
    assert "ID 1: trajectory of 3 points, run" in p.text("log-list")


def fill(p, element_id, text):
    box = p.by("#" + element_id)
    box.clear()
    if text:
        box.send_keys(text)


def test_a_lock_out_setting_asks_first_and_clear_unload_waits_out_the_drain(
        sim_factory, studio_factory, page):
    p = on_the_foot(sim_factory(*SERVOS), studio_factory, page, "table")
    p.wait(lambda: p.value("temperature_limit").startswith("80 "), what="the factory limit")
    sent = p.commands()
    fill(p, "in-temperature_limit", "-1")
    p.click("set-temperature_limit")  # before: written at once, the foot unloaded
    p.wait(lambda: p.by("#confirm").is_displayed(), what="the confirmation")
    assert "would unload at once" in p.text("confirm-text")
    p.click("confirm-no")
    p.wait(lambda: "Not written" in p.message(), what="the cancel said")
    assert p.commands() == sent
    p.click("set-temperature_limit")
    p.wait(lambda: p.by("#confirm").is_displayed(), what="the confirmation again")
    p.click("confirm-yes")
    p.wait(lambda: p.value("temperature_limit").startswith("-1 "), what="-1 written")
    p.panel("safety")
    p.wait(lambda: "over-temperature" in p.text("safety-flags"), what="the unload")
    p.panel("table")
    fill(p, "in-temperature_limit", "80")
    p.click("set-temperature_limit")  # raising it needs no confirmation
    p.wait(lambda: p.value("temperature_limit").startswith("80 "), what="80 written")
    p.panel("safety")
    p.click("clear-unload")  # right after: the foot still sees the cause for about 2 s
    p.wait(lambda: "Unload cleared after" in p.message(), timeout=10,
           what="the clear, after the drain")  # before: refused
    assert "still saw the cause" in p.message()
    p.wait(lambda: "no protection active" in p.text("safety-flags"), what="no unload")


def test_motion_and_id_forms_refuse_empty_and_decimal_values_in_words(
        sim_factory, studio_factory, page):
    p = on_the_foot(sim_factory(*SERVOS), studio_factory, page, "motion")
    sent = p.commands()
    for box, text, words in (("mv-acc", "", "acceleration is empty"),  # before: sent 0
                             ("mv-acc", "1.5", "1.5 is not a whole number"),  # before: 1
                             ("mv-goal", "", "goal is empty")):  # before: no message
        fill(p, "mv-acc", "36")
        fill(p, box, text)
        p.click("mv-go")
        p.wait(lambda: words.lower() in p.message().lower(), what="the refusal of " + repr(text))
        assert "Nothing was sent." in p.message()
    p.panel("ident")
    for text, words in (("", "new ID is empty"),  # before: sent ID 0
                        ("7.9", "7.9 is not a whole number")):  # before: sent 7
        fill(p, "id-new", text)
        p.click("id-go")
        p.wait(lambda: words.lower() in p.message().lower(), what="the refusal of " + repr(text))
    assert p.commands() == sent
