"""report.html of the bundled L corridor: its size, how fast headless Chromium draws the train
after opening it, the frame rate while it plays, and the time the page costs plan-and-run.

    python benchmarks/bench_report.py [--run DIR] [--seconds 3]

Targets (issue 26): at most 5 MB, the train drawn in under 2 s, at least 30 frames per second
while playing. Needs Debian's chromium and chromium-driver and selenium (the test extras).
The frame rate is counted by the page itself (requestAnimationFrame callbacks that drew a
frame in the last second); the load time runs from the request to the page saying it drew.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _browser_problem() -> str | None:
    """What is missing to drive a headless browser here (checked before any work), or None."""
    missing = []
    if not (shutil.which("chromium") or shutil.which("google-chrome")):
        missing.append("a browser (Debian: apt install chromium)")
    if not shutil.which("chromedriver"):
        missing.append("chromedriver (Debian: apt install chromium-driver)")
    try:
        import selenium  # noqa: F401
    except ImportError:
        missing.append("selenium (pip install -e '.[test]')")
    return "; ".join(missing) or None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", type=Path, help="a run folder (default: plan-and-run l_corridor)")
    ap.add_argument("--seconds", type=float, default=3.0, help="how long to play [s]")
    args = ap.parse_args()
    problem = _browser_problem()
    if problem:
        sys.exit(f"bench_report: not measured: it drives a headless browser and needs {problem}")
    run = args.run
    if run is None:
        run = Path(tempfile.mkdtemp()) / "l_corridor"
        exe = Path(sys.executable).with_name("plan-and-run")
        subprocess.run([str(exe), str(ROOT / "examples" / "l_corridor.toml"), "--out", str(run)],
                       check=True, capture_output=True)
    page = run / "report.html"
    log = (run / "run.log").read_text()
    drawn = [line for line in log.splitlines() if "report.html drawn in" in line]

    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium") or shutil.which("google-chrome")
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1400,1000"):
        options.add_argument(arg)
    try:
        drv = webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=options)
    except Exception as exc:  # a browser that cannot start here: say why, no traceback
        sys.exit(f"bench_report: not measured: chromium did not start: "
                 f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}")
    try:
        t0 = time.perf_counter()
        drv.get(page.resolve().as_uri())
        while not drv.execute_script("return !!(window.pushtrainReport && "
                                     "window.pushtrainReport.ready)"):
            time.sleep(0.005)
        load_s = time.perf_counter() - t0
        drv.execute_script("document.getElementById('speed').value = '1';"
                           "window.pushtrainReport.setRow(0); window.pushtrainReport.play();")
        time.sleep(args.seconds)
        fps = drv.execute_script("return window.pushtrainReport.state().fps")
    finally:
        drv.quit()
    size = page.stat().st_size / 1e6
    print(f"load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"report.html: {size:.2f} MB (target <= 5), train drawn {load_s:.2f} s after opening "
          f"(target < 2), {fps} frames per second playing (target >= 30)")
    if drawn:
        print("written by:", drawn[0].split("INFO ")[-1])


if __name__ == "__main__":
    main()
