"""report.html: the run's page, in a real browser (headless Debian chromium via selenium).

The browser tests are marked ``browser``; where no browser or driver can be started they are
skipped, and the skip says why (``.ci/run`` installs chromium and chromium-driver).
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from report_browser import open_page, severe_errors, slide_to

from pushtrain.report.html import MAX_ROWS, run_payload

ROOT = Path(__file__).resolve().parents[2]

SLIT = """
name = "slit"
[mission]
kind = "plan"
[train]
n = 2
[map]   # two rooms joined by a 0.5 m slit: a 0.6 m trailer cannot pass
free = [[0, 0], [5, 0], [5, 1.75], [6, 1.75], [6, 0], [11, 0], [11, 4], [6, 4], [6, 2.25],
        [5, 2.25], [5, 4], [0, 4]]
[start]
x = 3.0
y = 2.0
theta_deg = 180.0
[goal]
x = 9.0
y = 2.0
theta_deg = 180.0
"""

DOOR = """
name = "door"
[mission]
kind = "plan"
[train]
n = 3
[map]   # a 0.8 m corridor and a room below it through a 0.9 m door in a 0.1 m wall
free = [[0, 5], [10, 5], [10, 4.9], [8, 4.9], [8, 0], [13, 0], [13, 4.9], [10.9, 4.9],
        [10.9, 5], [16, 5], [16, 5.8], [0, 5.8]]
[start]
x = 4.5
y = 5.4
theta_deg = 180.0
[goal]
x = 10.45
y = 2.0
theta_deg = 90.0
"""


def _cli(*args, cwd=None):
    exe = Path(sys.executable).with_name("pushtrain")
    return subprocess.run([str(exe), *args], capture_output=True, text=True, cwd=cwd,
                          timeout=600)


@pytest.fixture(scope="module")
def corridor_run(tmp_path_factory):
    """plan-and-run of the bundled L corridor: its run folder."""
    out = tmp_path_factory.mktemp("report") / "l_corridor"
    proc = _cli("plan-and-run", str(ROOT / "examples" / "l_corridor.toml"), "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.fixture(scope="module")
def failed_plan(tmp_path_factory):
    """plan-and-run of a mission through a slit narrower than the trailer: its run folder."""
    base = tmp_path_factory.mktemp("slit")
    (base / "slit.toml").write_text(SLIT)
    proc = _cli("plan-and-run", str(base / "slit.toml"), "--out", str(base / "run"))
    # no way through the slit, proven before any search: bad input, exit 2 (README)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    return base / "run"


@pytest.fixture(scope="module")
def door_plan(tmp_path_factory):
    """plan-and-run of three trailers along a 0.8 m corridor and through a 0.9 m door off it
    (wide enough for the last trailer, too narrow a corridor to line up with the door)."""
    base = tmp_path_factory.mktemp("door")
    (base / "door.toml").write_text(DOOR)
    proc = _cli("plan-and-run", str(base / "door.toml"), "--out", str(base / "run"))
    assert proc.returncode == 1, proc.stdout + proc.stderr
    return base / "run"


def _payload(page: Path) -> dict:
    text = page.read_text(encoding="utf-8")
    m = re.search(r'<script type="application/json" id="report-data">(.*?)</script>', text, re.S)
    return json.loads(m.group(1).replace("<\\/", "</"))


# ---------------------------------------------------------------------- the file
def test_non_finite_numbers_become_json_null_in_the_page(tmp_path):
    """NaN and inf (a diverged run) are written as null: the page's data is strict JSON, which
    a browser's JSON.parse reads (it refuses NaN and Infinity)."""
    from pushtrain.report.html import write_table_page

    page = write_table_page(tmp_path / "t.html", "t", {"rate": math.nan, "big": math.inf},
                            ["x", "y"], [[1.0, -math.inf], [np.float64(math.nan), 2.0]])
    text = page.read_text()
    raw = re.search(r'<script type="application/json" id="report-data">(.*?)</script>', text,
                    flags=re.S).group(1)

    def refuse(name):
        raise ValueError(f"{name} in the page's JSON")

    data = json.loads(raw.replace("<\\/", "</"), parse_constant=refuse)
    assert data["summary"] == {"rate": None, "big": None}
    assert data["rows"] == [[1.0, None], [None, 2.0]]


def test_every_run_folder_has_one_self_contained_page(corridor_run):
    from pushtrain.cosim.result import load_results

    page = corridor_run / "report.html"
    text = page.read_text(encoding="utf-8")
    assert page.stat().st_size <= 5_000_000  # the limit for l_corridor
    # nothing from the network: no http(s) source, link or import
    assert not re.search(r"""(src|href)\s*=\s*["']?https?:""", text)
    assert "@import" not in text and "fetch(" not in text
    data = load_results(corridor_run)
    payload = _payload(page)
    rows = payload["rows"]
    # the view is decimated, every shown sample is a row of results.npz, the last included
    assert len(rows) <= MAX_ROWS and rows[0] == 0 and rows[-1] == len(data) - 1
    assert np.allclose(payload["t"], data["t"][rows], atol=1e-4)
    for i in range(4):
        assert np.allclose(payload["bodies"][i]["x"], data[f"x{i}"][rows], atol=1e-4)
    # results.npz itself is whole
    assert len(data) > len(rows)
    assert payload["summary"]["status"] == "goal_reached" == payload["status"]


def test_the_joint_panel_carries_the_joint_limit_and_the_force_panel_the_friction_limit():
    dtype = [(c, "f8") for c in ("t", "x0", "y0", "theta0", "x1", "y1", "theta1", "phi1",
                                 "F_lat1", "F_lat_max1")]
    data = np.zeros(50, dtype=dtype)
    data["t"] = np.arange(50) * 0.1
    data["phi1"] = np.radians(30.0)
    data["F_lat1"] = -20.0
    data["F_lat_max1"] = 40.0
    payload = run_payload(data, 1, phi_max_deg=80.0)
    panels = {p["key"]: p for p in payload["series"]}
    assert [lm["y"] for lm in panels["joints"]["limits"]] == [80.0, -80.0]
    assert panels["joints"]["lines"][0]["y"][0] == pytest.approx(30.0)
    assert panels["force"]["lines"][0]["y"][0] == pytest.approx(0.5)  # |F| / limit
    assert [lm["y"] for lm in panels["force"]["limits"]] == [1.0]


def test_view_prints_the_page_where_no_browser_is_known(corridor_run, monkeypatch):
    from click.testing import CliRunner

    from pushtrain.cli.main import cli

    monkeypatch.setenv("BROWSER", "")
    monkeypatch.setattr("webbrowser._tryorder", [], raising=False)
    monkeypatch.setattr("webbrowser._browsers", {}, raising=False)
    monkeypatch.setattr("webbrowser.register_standard_browsers", lambda: None)
    result = CliRunner().invoke(cli, ["view", str(corridor_run)])
    assert result.exit_code == 0
    page = (corridor_run / "report.html").resolve()
    assert result.output.strip().splitlines()[-1] == str(page)
    assert f"no browser found here; open {page.as_uri()}" in result.output
    bad = CliRunner().invoke(cli, ["view", str(corridor_run / "nothing")])
    assert bad.exit_code == 2 and "RUN_DIR" in bad.output and "not a folder" in bad.output


def test_a_failed_plan_leaves_a_page_with_its_bottleneck(failed_plan):
    payload = _payload(failed_plan / "report.html")
    assert payload["kind"] == "failure" and payload["summary"]["reason"] == "unreachable"
    b = payload["bottleneck"]
    assert 5.0 <= b["x"] <= 6.0 and b["width"] == pytest.approx(0.5, abs=0.1)


def test_a_door_the_train_cannot_line_up_with_is_the_place_on_the_failure_page(door_plan):
    """The page's marker is the door (its middle, 10-10.9 m by 4.9-5 m), labelled with the
    corridor's width in front of it and what a steady turn into it needs, as the message
    says."""
    payload = _payload(door_plan / "report.html")
    b = payload["bottleneck"]
    assert 10.0 <= b["x"] <= 10.9 and 4.8 <= b["y"] <= 5.1, b
    assert b["what"].startswith("door the train cannot line up with (0.90 m door")
    assert b["width"] == pytest.approx(0.8, abs=0.02) and b["needed"] > 0.85
    assert f"needs {b['needed']:.2f} m of corridor in front of it" in payload["message"]


# ---------------------------------------------------------------------- in a browser
@pytest.mark.browser
def test_the_page_loads_without_errors_and_the_slider_moves_the_train(browser, corridor_run):
    from pushtrain.cosim.result import load_results

    open_page(browser, corridor_run / "report.html")
    assert severe_errors(browser) == []
    data = load_results(corridor_run)
    rows = _payload(corridor_run / "report.html")["rows"]
    seen = []
    for k in (len(rows) // 3, (3 * len(rows)) // 4):
        state = slide_to(browser, k)
        r = state["resultRow"]
        assert r == rows[k] and state["t"] == pytest.approx(data["t"][r], abs=1e-4)
        # the bodies drawn (read back from the canvas) are the recorded poses at that time
        assert len(state["bodies"]) == 4
        for i, (x, y, th) in enumerate(state["bodies"]):
            assert x == pytest.approx(data[f"x{i}"][r], abs=2e-3)
            assert y == pytest.approx(data[f"y{i}"][r], abs=2e-3)
            assert math.remainder(th - data[f"theta{i}"][r], 2 * math.pi) == pytest.approx(
                0.0, abs=2e-3)
        # every plot's cursor stands at that time
        assert state["cursors"] and all(c == pytest.approx(state["t"], abs=1e-6)
                                        for c in state["cursors"])
        seen.append(state["bodies"][0])
    assert math.dist(seen[0][:2], seen[1][:2]) > 1.0  # the train moved
    assert severe_errors(browser) == []


@pytest.mark.browser
def test_the_plots_stay_drawn_when_the_window_is_resized(browser, corridor_run):
    open_page(browser, corridor_run / "report.html")
    count = ("const c = document.querySelectorAll('.plot canvas')[arguments[0]];"
             "const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;"
             "let n = 0; for (let i = 0; i < d.length; i += 4) {"
             "  if (d[i + 3] > 0 && (d[i] < 200 || d[i + 1] < 200 || d[i + 2] < 200)) n++; }"
             "return n;")
    before = browser.execute_script(count, 2)
    browser.set_window_size(1200, 900)
    time.sleep(0.3)  # the resize event is handled asynchronously
    after = browser.execute_script(count, 2)
    browser.set_window_size(1400, 1000)
    assert before > 1000 and after > 1000  # lines, labels and the cursor, not a blank canvas


@pytest.mark.browser
def test_a_click_on_a_plot_moves_the_train_to_that_time(browser, corridor_run):
    from selenium.webdriver.common.action_chains import ActionChains

    open_page(browser, corridor_run / "report.html")
    plot = browser.find_elements("css selector", ".plot canvas")[2]
    width = plot.size["width"]
    times = []
    for fraction in (0.3, 0.8):
        ActionChains(browser).move_to_element_with_offset(
            plot, int((fraction - 0.5) * width), 0).click().perform()
        state = browser.execute_script("return window.pushtrainReport.state()")
        slider = int(browser.find_element("id", "slider").get_attribute("value"))
        assert slider == state["row"]
        times.append(state["t"])
    assert times[1] > times[0] + 20.0  # half the plot's width apart, of a 126 s run
    assert severe_errors(browser) == []


@pytest.mark.browser
def test_a_time_between_two_samples_shows_the_nearer_one(browser, corridor_run):
    """What a click on a plot does (setTime): a time just past a sample shows that sample, a
    time just before the next one shows the next; checked against the page's own times."""
    open_page(browser, corridor_run / "report.html")
    times = browser.execute_script(
        "const r = window.pushtrainReport; const out = [];"
        "for (let k = 0; k < 6; k++) { r.setRow(k * 37 + 5); out.push(r.state().t); }"
        "r.setRow(0); return out;")
    rows = [k * 37 + 5 for k in range(6)]
    nexts = browser.execute_script(
        "const r = window.pushtrainReport;"
        "return arguments[0].map((k) => { r.setRow(k + 1); return r.state().t; });", rows)
    for row, t, t_next in zip(rows, times, nexts, strict=True):
        assert t_next > t
        for fraction, want in ((0.1, row), (0.4, row), (0.6, row + 1), (0.9, row + 1)):
            state = browser.execute_script(
                "window.pushtrainReport.setTime(arguments[0]);"
                "return window.pushtrainReport.state();", t + fraction * (t_next - t))
            assert state["row"] == want, (row, fraction, state["row"])
    assert severe_errors(browser) == []


@pytest.mark.browser
def test_play_advances_the_train(browser, corridor_run):
    open_page(browser, corridor_run / "report.html")
    browser.execute_script("window.pushtrainReport.setRow(0);")
    browser.find_element("id", "play").click()
    time.sleep(0.5)
    state = browser.execute_script("return window.pushtrainReport.state()")
    browser.find_element("id", "play").click()
    assert state["playing"] and state["row"] > 0 and state["t"] > 0.0


def _failure_page(browser, run: Path) -> tuple[dict, str]:
    """Open a failed plan's page: no severe errors, a failure page marking its bottleneck where
    the data puts it. Its bottleneck (the data) and the legend's text."""
    open_page(browser, run / "report.html")
    assert severe_errors(browser) == []
    state = browser.execute_script("return window.pushtrainReport.state()")
    b = _payload(run / "report.html")["bottleneck"]
    assert state["kind"] == "failure"
    assert state["bottleneck"] == pytest.approx([b["x"], b["y"]], abs=1e-6)
    return b, browser.find_element("id", "legend").text


@pytest.mark.browser
def test_a_failed_plan_page_shows_the_bottleneck(browser, failed_plan):
    b, legend = _failure_page(browser, failed_plan)
    assert f"bottleneck at ({b['x']:.2f}, {b['y']:.2f})" in legend and "m needed" in legend


@pytest.mark.browser
def test_a_wide_enough_narrowest_place_is_not_drawn_as_the_cause(browser, tmp_path):
    """A search that gave up (the T junction's K-turn in 0.01 s of budget) where every way is
    wide enough: the page names the widest way's narrowest place as wide enough, in grey, not
    as the bottleneck (it ringed a 2 m corridor in red as one)."""
    examples = Path(__file__).resolve().parents[2] / "examples"
    text = (examples / "t_junction_kturn.toml").read_text()
    text = text.replace("[planner]\n", "[planner]\ntime_budget = 0.01\n") \
        if "[planner]" in text else text + "\n[planner]\ntime_budget = 0.01\n"
    (tmp_path / "short.toml").write_text(text)
    proc = _cli("plan-and-run", str(tmp_path / "short.toml"), "--out", str(tmp_path / "run"),
                "--no-plots")
    assert proc.returncode == 1, proc.stdout + proc.stderr
    b, legend = _failure_page(browser, tmp_path / "run")
    assert b["what"] == "bottleneck" and b["width"] >= b["needed"]
    assert (f"narrowest place of the widest way at ({b['x']:.2f}, {b['y']:.2f}): "
            f"{b['width']:.2f} m wide, {b['needed']:.2f} m needed (wide enough") in legend, legend
    assert "bottleneck at" not in legend


@pytest.mark.browser
def test_a_sweep_page_shows_the_run_whose_row_is_clicked(browser, tmp_path):
    from pushtrain.studies.sweep_report import write_report

    rows = [{"index": k, "sensors.joint_bias_deg[2]": float(k), "status": "goal_reached",
             "ok": True, "error": "", "steady_lat_m": 0.01 * k} for k in range(6)]
    rows[4].update(status="jackknifed", ok=False, error="jackknife at t = 3 s")
    parameters = [{"path": "sensors.joint_bias_deg[2]", "label": "bias [deg]"}]
    report = write_report(tmp_path, rows, parameters, name="bias", plots=True)
    page = Path(report["files"]["page"])
    assert page == tmp_path / "report.html"
    open_page(browser, page)
    assert severe_errors(browser) == []
    assert browser.find_elements("css selector", "#images-panel img")  # the sweep's plots
    browser.find_elements("css selector", "#runs tr.row")[4].click()
    shown = dict(browser.execute_script("return window.pushtrainReport.state().shown"))
    assert shown["index"] == "4" and shown["status"] == "jackknifed"
    assert shown["error"] == "jackknife at t = 3 s"
    # sorting by a column keeps each row whole
    browser.find_elements("css selector", "#runs th")[-1].click()  # steady_lat_m, ascending
    browser.find_elements("css selector", "#runs th")[-1].click()  # descending
    first = browser.find_elements("css selector", "#runs tr.row")[0]
    first.click()
    shown = dict(browser.execute_script("return window.pushtrainReport.state().shown"))
    assert shown["index"] == "5" and shown["steady_lat_m"] == "0.05000"


@pytest.mark.browser
def test_a_failed_plan_page_shows_the_door_the_train_cannot_line_up_with(browser, door_plan):
    b, legend = _failure_page(browser, door_plan)
    assert (f"door the train cannot line up with (0.90 m door, 90 deg turn; the corridor in "
            f"front of it) at "
            f"({b['x']:.2f}, {b['y']:.2f}): {b['width']:.2f} m wide, {b['needed']:.2f} m "
            "needed") in legend, legend
