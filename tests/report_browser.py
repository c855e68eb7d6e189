"""The report pages' browser helpers, shared by the tests of tests/report: open a page in
headless Debian chromium (selenium) and wait for the train to be drawn, read the console's
errors, move the slider as a user does. The ``browser`` fixture is in tests/report/conftest.py."""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import pytest


def chromium_binary():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        if shutil.which(name):
            return shutil.which(name)
    return None


def browser_driver():
    """A headless chromium driver (a generator: yields it, quits it); skips saying why
    where none starts."""
    binary, driver = chromium_binary(), shutil.which("chromedriver")
    if binary is None or driver is None:
        pytest.skip("no browser: install Debian's chromium and chromium-driver "
                    "(.ci/run does) to run the report's browser tests")
    webdriver = pytest.importorskip("selenium.webdriver",
                                    reason="selenium is missing (pip install -e '.[test]')")
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = binary
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1400,1000",
                "--disable-dev-shm-usage"):
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    try:
        drv = webdriver.Chrome(service=Service(driver), options=options)
    except Exception as exc:  # a browser that cannot start here is a skip that says why
        pytest.skip(f"chromium did not start: {str(exc).splitlines()[0]}")
    drv.set_script_timeout(30)
    yield drv
    drv.quit()


def open_page(drv, page: Path) -> float:
    """Load ``page`` and wait until the train is drawn; the seconds it took."""
    t0 = time.perf_counter()
    drv.get(page.resolve().as_uri())
    deadline = time.monotonic() + 30
    while not drv.execute_script("return !!(window.pushtrainReport && "
                                 "window.pushtrainReport.ready)"):
        assert time.monotonic() < deadline, drv.get_log("browser")
        time.sleep(0.02)
    return time.perf_counter() - t0


def severe_errors(drv) -> list:
    return [e for e in drv.get_log("browser") if e["level"] == "SEVERE"]


def slide_to(drv, k: int) -> dict:
    """Move the page's slider to view row ``k`` as a user does (an input event)."""
    return drv.execute_script(
        "const s = document.getElementById('slider'); s.value = String(arguments[0]);"
        "s.dispatchEvent(new Event('input')); return window.pushtrainReport.state();", k)
