"""Browser tests of Servo Studio: servo-sim (started as tools/python/tests/conftest.py
does), the studio as a child process, and a real headless Chromium (selenium)."""

import importlib.util
import os
import sys
import time

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
PYROOT = os.path.dirname(HERE)
sys.path.insert(0, PYROOT)

from servobus.studio import browser  # noqa: E402
from servobus.studio.process import Studio  # noqa: E402

# The SDK tests' servo-sim fixture code, loaded under another module name.
_spec = importlib.util.spec_from_file_location(
    "sdk_conftest", os.path.join(PYROOT, "tests", "conftest.py"))
sdk_conftest = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(sdk_conftest)


sim_factory = sdk_conftest.sim_factory  # the same fixture: servo-sims stopped at the end
sys.path.append(os.path.join(PYROOT, "tests"))  # wire.py: the tap in front of servo-sim
from wire import WireTap  # noqa: E402
from raw import Api  # noqa: E402


def pytest_configure(config):
    config.addinivalue_line("markers", "browser: drives headless Chromium (CTest "
                            "python.studio, with a core of its own); the others use raw HTTP "
                            "clients")


def pytest_collection_modifyitems(items):
    for item in items:
        if "chromium" in item.fixturenames:
            item.add_marker(pytest.mark.browser)


@pytest.fixture
def studio_factory():
    studios = []

    def start(bus_url, *extra):
        s = Studio(bus_url, *extra)
        studios.append(s)
        return s
    yield start
    for s in studios:
        assert s.stop() == 0, s.stderr


class Tapped:
    """servo-sim, the wire tap in front of it, the studio on the tap, and a raw client
    of the studio."""

    def __init__(self, sim, tap, studio):
        self.sim, self.tap, self.studio = sim, tap, studio
        self.api = Api(studio)


@pytest.fixture
def tapped(sim_factory, studio_factory):
    """Start servo-sim with servos, a tap, and the studio on it (rfc2217: through the
    baud model; studio_args: more `servoctl studio` options). Over tcp:// the studio
    talks at 115200 baud: servo-sim's servos hear a raw client at any baud and answer
    at their own, so the start-up scan of low IDs takes 0.4 s, not 2.6 s."""
    taps = []

    def start(*servos, studio_args=(), rfc2217=False, state_dir=None):
        sim = sim_factory(*servos, state_dir=state_dir)
        tap = WireTap(sim.port)
        taps.append(tap)
        if not rfc2217 and "--baud" not in studio_args:
            studio_args = ("--baud", "115200") + tuple(studio_args)
        studio = studio_factory(tap.rfc2217_url if rfc2217 else tap.url, *studio_args)
        return Tapped(sim, tap, studio)
    yield start
    for tap in taps:
        tap.close()


@pytest.fixture(scope="session")
def chromium(tmp_path_factory):
    why = browser.missing()
    if why:
        pytest.fail("the studio's browser tests need a headless Chromium: " + why)
    downloads = tmp_path_factory.mktemp("downloads")
    d = browser.chromium(downloads=downloads)
    d.downloads = downloads
    yield d
    d.quit()


class Page:
    """The studio's page in Chromium, with the waits the tests need."""

    def __init__(self, driver, url):
        self.d = driver
        self.url = url
        driver.get(url)

    def by(self, css):
        return self.d.find_element("css selector", css)

    def all(self, css):
        return self.d.find_elements("css selector", css)

    def text(self, element_id):
        """The element's text, whether its panel is shown or not (live readouts are
        redrawn at every sample: an element replaced meanwhile is looked up again)."""
        from selenium.common.exceptions import StaleElementReferenceException
        for _ in range(5):
            try:
                return self.d.find_element("id", element_id).get_attribute(
                    "textContent").strip()
            except StaleElementReferenceException:
                continue
        raise AssertionError("#%s keeps being replaced" % element_id)

    def click(self, element_id):
        self.d.find_element("id", element_id).click()

    def wait(self, predicate, timeout=15.0, what="the condition"):
        deadline = time.monotonic() + timeout
        last = None
        while time.monotonic() < deadline:
            try:
                last = predicate()
            except Exception as e:  # noqa: BLE001 (an element not there yet)
                last = e
            if last and not isinstance(last, Exception):
                return last
            time.sleep(0.05)
        raise AssertionError("timed out waiting for %s (last: %r; message bar: %r)" % (
            what, last, self.message()))

    def download(self, buttons, patterns):
        """Empty the download folder, click each export button, and return the file
        that came for each glob pattern, in order, once it is there."""
        for old in self.d.downloads.iterdir():
            old.unlink()
        for b in buttons:
            self.click(b)
        return [self.wait(lambda g=g: list(self.d.downloads.glob(g)), what="a file " + g)[0]
                for g in patterns]

    def lines(self, path):
        """The lines of a downloaded text file, once it has any."""
        return self.wait(lambda: path.read_text().splitlines(), what="the lines of " + path.name)

    def message(self):
        try:
            return self.text("message")
        except Exception:  # noqa: BLE001
            return None

    def panel(self, name):
        self.by("nav button[data-panel=%s]" % name).click()
        self.wait(lambda: self.by("#panel-%s" % name).is_displayed(), what="panel " + name)

    def scan_rows(self):
        return [[td.text for td in tr.find_elements("css selector", "td")]
                for tr in self.all("#scan-table tbody tr")]

    def wait_scanned(self, n, timeout=20.0):
        return self.wait(lambda: len(self.scan_rows()) == n and self.scan_rows(),
                         timeout, "%d servos in the scan table" % n)

    def select(self, servo_id):
        self.panel("scan")
        self.wait(lambda: self.by("#scan-table tr[data-id='%d'] button" % servo_id),
                  what="ID %d in the scan table" % servo_id).click()
        self.wait(lambda: "ID %d " % servo_id in self.text("table-who"),
                  what="ID %d selected" % servo_id)

    def value(self, reg):
        return self.text("val-" + reg)

    def commands(self):
        return int(self.d.find_element("id", "log-count").get_attribute("textContent"))

    def readout(self):
        """Live sample of the selected servo as the page holds it."""
        return self.d.execute_script("return window.studio.sample")


@pytest.fixture
def page(chromium):
    """Open the studio's page; at the end, the page must have logged no error (a
    script error would leave panels silently stale)."""
    chromium.get_log("browser")  # what earlier tests left

    def open_page(url):
        return Page(chromium, url)
    yield open_page
    # A refusal is an HTTP 4xx with a sentence the page shows: Chromium logs it as a
    # failed load, which is not a script error.
    errors = [e["message"] for e in chromium.get_log("browser") if e["level"] == "SEVERE"
              and "the server responded with a status of 4" not in e["message"]]
    chromium.get("about:blank")  # before the studio stops: no reconnecting page left
    assert not errors, errors
