"""Headless Chromium for the studio's screenshots and browser tests (Debian's chromium,
chromium-driver and python3-selenium)."""

import os
import shutil

CHROMIUM = os.environ.get("STUDIO_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
DRIVER = os.environ.get("STUDIO_CHROMEDRIVER") or shutil.which("chromedriver") or \
    "/usr/bin/chromedriver"


def missing():
    """What is missing for a headless browser, in words, or ''."""
    out = []
    try:
        import selenium  # noqa: F401
    except ImportError:
        out.append("python3-selenium")
    for path, pkg in ((CHROMIUM, "chromium"), (DRIVER, "chromium-driver")):
        if not os.access(path, os.X_OK):
            out.append(pkg)
    return ("install %s (tools/install-deps.sh)" % ", ".join(out)) if out else ""


def chromium(width=1400, height=1000, downloads=None):
    """A headless Chromium driven by chromedriver. In a container the sandbox and
    /dev/shm are not available: --no-sandbox, --disable-dev-shm-usage."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for a in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--disable-gpu",
              "--window-size=%d,%d" % (width, height), "--hide-scrollbars",
              "--force-device-scale-factor=1"):
        opts.add_argument(a)
    if downloads:
        opts.add_experimental_option("prefs", {
            "download.default_directory": str(downloads),
            "download.prompt_for_download": False})
    return webdriver.Chrome(service=Service(DRIVER), options=opts)
