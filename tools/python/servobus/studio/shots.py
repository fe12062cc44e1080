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


def take(out_dir, sim_path):
    os.makedirs(out_dir, exist_ok=True)
    tmp = tempfile.mkdtemp(prefix="studio-shots-")
    sim, url = start_sim(sim_path, state_dir=tmp)
    studio = Studio(url)
    d = browser.chromium(1400, 900)
    by = lambda css: d.find_element("css selector", css)  # noqa: E731
    text = lambda i: d.find_element("id", i).get_attribute("textContent")  # noqa: E731
    written = []

    def shot(name):
        path = os.path.join(out_dir, name + ".png")
        d.save_screenshot(path)
        written.append(path)

    def panel(name):
        by("nav button[data-panel=%s]" % name).click()
        time.sleep(0.3)

    def fill(element_id, value):
        box = d.find_element("id", element_id)
        box.clear()
        box.send_keys(value)

    try:
        d.get(studio.url)
        _wait(lambda: len(d.find_elements("css selector", "#scan-table tbody tr")) == 3)
        shot("scan")
        by("#scan-table tr[data-id='2'] button").click()
        _wait(lambda: "ID 2 " in text("table-who"))
        panel("table")
        _wait(lambda: text("val-return_delay").startswith("16"))
        fill("in-return_delay", "300")
        by("#set-return_delay").click()
        fill("in-temperature_limit", "70")
        by("#set-temperature_limit").click()
        _wait(lambda: text("val-temperature_limit").startswith("70"))
        shot("table")
        panel("motion")
        fill("mv-goal", "300")
        fill("mv-speed", "60")
        by("#mv-go").click()
        time.sleep(2.0)
        shot("motion")
        _wait(lambda: "still" in text("motion-readout"), 10)
        fill("mv-goal", "120")
        fill("mv-speed", "120")
        by("#mv-go").click()
        panel("plot")
        time.sleep(2.5)
        shot("plot")
        panel("safety")
        time.sleep(1.2)
        shot("safety")
        image = os.path.join(tmp, "foot-v7.bin")
        with open(image, "wb") as f:
            f.write(I.build(16384, 7, VARIANTS["foot"].model_number))
        panel("firmware")
        by("#fw-file").send_keys(image)
        by("#fw-go").click()
        _wait(lambda: text("fw-after") == "7", 60)
        shot("firmware")
        panel("ident")
        fill("id-new", "3")
        shot("ident")
        by("#reset-go").click()
        time.sleep(0.3)
        shot("reset")
        by("#confirm-no").click()
        panel("scan")
        by("#scan-table tr[data-id='1'] button").click()  # the arm: homing, live
        _wait(lambda: "ID 1 " in text("motion-who"))
        panel("motion")
        by("#home-go").click()
        _wait(lambda: text("home-status") == "running", 10)
        time.sleep(1.5)
        shot("homing")
        panel("log")
        shot("log")
    finally:
        d.quit()
        studio.stop()
        sim.terminate()
        sim.wait()
    return written


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
