"""Screenshots of every panel of the studio for the docs, taken in headless Chromium
against servo-sim with an arm, a foot and a base.

    python3 -m servobus.studio.shots docs/studio [SERVO_SIM]"""

import os
import sys
import tempfile
import time

from .. import VARIANTS
from .. import image as I
from . import browser
from .onsim import REPO, start_sim
from .process import Studio


def _wait(predicate, timeout=20.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            if predicate():
                return
        except Exception:  # noqa: BLE001 (element not there yet)
            pass
        time.sleep(0.1)
    raise SystemExit("shots: timed out")


class _Tour:
    """The studio's page in headless Chromium, and the screenshots taken of it."""

    def __init__(self, driver, out_dir):
        self.d = driver
        self.out_dir = out_dir
        self.written = []

    def by(self, css):
        return self.d.find_element("css selector", css)

    def text(self, element_id):
        return self.d.find_element("id", element_id).get_attribute("textContent")

    def shot(self, name):
        path = os.path.join(self.out_dir, name + ".png")
        self.d.save_screenshot(path)
        self.written.append(path)

    def panel(self, name):
        self.by("nav button[data-panel=%s]" % name).click()
        time.sleep(0.3)

    def fill(self, element_id, value):
        box = self.d.find_element("id", element_id)
        box.clear()
        box.send_keys(value)


def _table_and_motion(t):
    """Scan, the foot's control table with two edits, a move and the live plot."""
    _wait(lambda: len(t.d.find_elements("css selector", "#scan-table tbody tr")) == 3)
    t.shot("scan")
    t.by("#scan-table tr[data-id='2'] button").click()
    _wait(lambda: "ID 2 " in t.text("table-who"))
    t.panel("table")
    _wait(lambda: t.text("val-return_delay").startswith("16"))
    t.fill("in-return_delay", "300")
    t.by("#set-return_delay").click()
    t.fill("in-temperature_limit", "70")
    t.by("#set-temperature_limit").click()
    _wait(lambda: t.text("val-temperature_limit").startswith("70"))
    t.shot("table")
    t.panel("motion")
    t.fill("mv-goal", "300")
    t.fill("mv-speed", "60")
    t.by("#mv-go").click()
    time.sleep(2.0)
    t.shot("motion")
    _wait(lambda: "still" in t.text("motion-readout"), 10)
    t.fill("mv-goal", "120")
    t.fill("mv-speed", "120")
    t.by("#mv-go").click()
    t.panel("plot")
    time.sleep(2.5)
    t.shot("plot")
    t.panel("safety")
    time.sleep(1.2)
    t.shot("safety")


def _expert(t):
    """Issue 29's panels: the console, a register plot, all servos, the trajectory
    editor and a configuration diff (the foot selected)."""
    t.panel("console")
    t.fill("con-entry", "D5 5D 02 04 02 2E 01")
    t.by("#con-send").click()
    _wait(lambda: "present_temperature" in t.text("con-answer"))
    time.sleep(0.5)
    t.shot("console")
    t.panel("scope")
    for sid in ("1", "2", "3"):
        t.by(".scope-id[value='%s']" % sid).click()
    for reg in ("present_speed", "present_temperature"):
        t.by("#scope-reg option[value='%s']" % reg).click()
        t.by("#scope-add").click()
        time.sleep(0.3)
    t.panel("motion")
    t.fill("mv-goal", "250")
    t.fill("mv-speed", "120")
    t.by("#mv-go").click()
    t.panel("scope")
    time.sleep(3.0)
    t.shot("scope")
    t.by("#scope-clear").click()
    t.panel("dash")
    _wait(lambda: len(t.d.find_elements("css selector", "#dash-table tbody tr")) == 3)
    time.sleep(1.0)
    t.shot("dashboard")
    t.panel("trajed")
    time.sleep(1.0)
    t.by("#te-run").click()
    time.sleep(4.0)
    t.shot("trajectory")
    t.panel("config")
    t.by("#cfg-a option[value='2']").click()
    t.by("#cfg-b option[value='1']").click()
    t.by("#cfg-diff").click()
    time.sleep(1.0)
    t.shot("config")


def _firmware_ident_homing(t, tmp):
    """A firmware update of the foot, the ID panel, the reset dialog, the arm homing,
    the log."""
    image = os.path.join(tmp, "foot-v7.bin")
    with open(image, "wb") as f:
        f.write(I.build(16384, 7, VARIANTS["foot"].model_number))
    t.panel("firmware")
    t.by("#fw-file").send_keys(image)
    t.by("#fw-go").click()
    _wait(lambda: t.text("fw-after") == "7", 60)
    t.shot("firmware")
    t.panel("ident")
    t.fill("id-new", "3")
    t.shot("ident")
    t.by("#reset-go").click()
    time.sleep(0.3)
    t.shot("reset")
    t.by("#confirm-no").click()
    t.panel("scan")
    t.by("#scan-table tr[data-id='1'] button").click()  # the arm: homing, live
    _wait(lambda: "ID 1 " in t.text("motion-who"))
    t.panel("motion")
    t.by("#home-go").click()
    _wait(lambda: t.text("home-status") == "running", 10)
    time.sleep(1.5)
    t.shot("homing")
    t.panel("log")
    t.shot("log")


def take(out_dir, sim_path):
    """Every screenshot of docs/studio.md, written to out_dir: the paths."""
    os.makedirs(out_dir, exist_ok=True)
    tmp = tempfile.mkdtemp(prefix="studio-shots-")
    sim, url = start_sim(sim_path, state_dir=tmp)
    studio = Studio(url)
    d = browser.chromium(1400, 900)
    tour = _Tour(d, out_dir)
    try:
        d.get(studio.url)
        _table_and_motion(tour)
        _expert(tour)
        _firmware_ident_homing(tour, tmp)
    finally:
        d.quit()
        studio.stop()
        sim.terminate()
        sim.wait()
    return tour.written


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if not argv:
        print(__doc__, file=sys.stderr)
        return 2
    why = browser.missing()
    if why:
        print("shots: " + why, file=sys.stderr)
        return 1
    sim = argv[1] if len(argv) > 1 else os.path.join(REPO, "build", "host", "servo-sim")
    for path in take(argv[0], sim):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
