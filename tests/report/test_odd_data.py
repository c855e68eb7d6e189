"""The pictures and the page of a run whose table holds NaN, inf, one row or none (a diverged
or interrupted run, issue #38 item 9): every file is drawn from what is finite and says, in
red under the figure or as a note on the page, which columns were not; nothing raises and no
warning reaches the user."""

import json
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image
from report_browser import open_page, severe_errors, slide_to

from pushtrain.cli.main import cli
from pushtrain.report import GIF_FILE, HTML_FILE, PNG_FILES

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
N = 3


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A short scripted run of straight_push (no pictures): its folder, table and scenario."""
    from pushtrain.cosim.result import load_results
    from pushtrain.mission.scenario import load_scenario

    base = tmp_path_factory.mktemp("odd")
    scenario = base / "short.toml"
    scenario.write_text((EXAMPLES / "straight_push.toml").read_text() + "horizon = 3.0\n")
    out = base / "run"
    result = CliRunner().invoke(cli, ["run", str(scenario), "--plots", "none", "--out",
                                      str(out)])
    assert result.exit_code in (0, 1), result.output
    return out, load_results(out), load_scenario(str(scenario))


def _variant(data, kind):
    d = data.copy()
    if kind == "diverged":  # every value but the time NaN from the middle on
        for name in d.dtype.names:
            if name != "t":
                d[name][len(d) // 2:] = np.nan
    elif kind == "some_inf":
        d["x2"][100:200] = np.inf
        d["e_lat"][50] = -np.inf
        d["F_lat1"][:] = np.nan
    elif kind == "all_nan":
        for name in d.dtype.names:
            if name != "t":
                d[name][:] = np.nan
    elif kind == "one_row":
        d = d[:1]
    elif kind == "no_rows":
        d = d[:0]
    return d


def _draw(name, data, sc, out):
    from pushtrain.cli.plotting import footprints_of, keep_out_of
    from pushtrain.mission.runner import geometry_of, world_of
    from pushtrain.report.plots import plot_file

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning may escape to the user
        return plot_file(name, data, N, out, world=world_of(sc), footprints=footprints_of(sc),
                         geometry=geometry_of(sc), status="failed", summary={"status": "x"},
                         phi_max_deg=sc.train.phi_max_deg, keep_out=keep_out_of(sc))


def _red_in_bottom_strip(png: Path) -> int:
    """Pixels of the note's red (matplotlib's tab:red, #d62728) in the lowest 4 % of the
    picture, where the note is written."""
    with Image.open(png) as image:
        rgb = np.asarray(image.convert("RGB"), dtype=int)
    strip = rgb[int(0.96 * len(rgb)):]
    return int(np.count_nonzero(np.abs(strip - [214, 39, 40]).sum(axis=2) < 60))


def _payload(page: Path) -> dict:
    text = page.read_text(encoding="utf-8")
    m = re.search(r'<script type="application/json" id="report-data">(.*?)</script>', text, re.S)
    return json.loads(m.group(1).replace("<\\/", "</"))


@pytest.mark.parametrize("kind", ["diverged", "some_inf", "all_nan", "one_row", "no_rows"])
def test_every_picture_is_drawn_from_odd_data(run, tmp_path, kind):
    _, data, sc = run
    odd = _variant(data, kind)
    for name in PNG_FILES + (GIF_FILE, HTML_FILE):
        path = _draw(name, odd, sc, tmp_path)
        assert path.is_file() and path.stat().st_size > 1000, name
        if name != HTML_FILE:
            with Image.open(path) as image:
                image.load()
    payload = _payload(tmp_path / HTML_FILE)
    assert len(payload["t"]) == min(len(odd), len(payload["rows"]))
    if kind in ("one_row", "no_rows"):
        assert payload["notes"] == ([] if kind == "one_row" else
                                    ["the results have no row with a finite time: nothing to "
                                     "show over time"])


def test_the_pictures_say_which_values_were_not_finite(run, tmp_path):
    _, data, sc = run
    odd = _variant(data, "some_inf")
    rows = len(odd)
    t = np.asarray(odd["t"])
    expected = [f"x2 (100 of {rows} rows from t = {t[100]:.2f} s)",
                f"e_lat (1 of {rows} rows from t = {t[50]:.2f} s)",
                f"F_lat1 ({rows} of {rows} rows from t = {t[0]:.2f} s)"]
    clean = tmp_path / "clean"
    clean.mkdir()
    for name in PNG_FILES:
        _draw(name, odd, sc, tmp_path)
        _draw(name, data, sc, clean)
        assert _red_in_bottom_strip(tmp_path / name) > 20, name  # the note, in red
        assert _red_in_bottom_strip(clean / name) == 0, name
    _draw(HTML_FILE, odd, sc, tmp_path)
    payload = _payload(tmp_path / HTML_FILE)
    (note,) = payload["notes"]
    assert note.startswith("not finite (NaN or inf), not drawn: ")
    for part in expected:
        assert part in note, (part, note)
    # the shown rows with x2 infinite carry no value for it (null), the others theirs
    shown = np.asarray(payload["rows"])
    x2 = payload["bodies"][2]["x"]
    bad = (shown >= 100) & (shown < 200)
    assert bad.any() and all(x2[k] is None for k in np.flatnonzero(bad))
    assert all(x2[k] == pytest.approx(odd["x2"][r], abs=1e-4)
               for k, r in enumerate(shown) if not bad[k])


@pytest.mark.slow
def test_a_diverged_run_through_the_cli_says_so(run, tmp_path, monkeypatch):
    """A run whose results turn NaN half way: exit as the run says, the page written, one
    warning line naming the columns, no traceback."""
    from pushtrain.mission import runner

    real = runner.run_scenario

    def diverging(*args, **kwargs):
        result = real(*args, **kwargs)
        for name in result.data.dtype.names:
            if name != "t":
                result.data[name][len(result.data) // 2:] = np.nan
        return result

    monkeypatch.setattr(runner, "run_scenario", diverging)
    scenario = tmp_path / "short.toml"
    scenario.write_text((EXAMPLES / "straight_push.toml").read_text() + "horizon = 2.0\n")
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["run", str(scenario), "--plots", "all", "--gif",
                                      "--plot-processes", "0", "--out", str(out)])
    assert result.exit_code in (0, 1), result.output
    assert "Traceback" not in result.output and "could not draw" not in result.output
    assert "not finite (NaN or inf), not drawn: x0" in result.output
    for name in PNG_FILES + (GIF_FILE, HTML_FILE):
        assert (out / name).is_file(), name
    assert _payload(out / HTML_FILE)["notes"]


@pytest.mark.browser
@pytest.mark.parametrize("kind", ["diverged", "some_inf", "no_rows", "one_row"])
def test_the_page_of_odd_data_opens_and_draws_what_is_finite(run, tmp_path, browser, kind):
    """In headless chromium: no script error, the notes shown, the slider works, and at a row
    whose poses are NaN no body is drawn while at a finite row all are."""
    _, data, sc = run
    odd = _variant(data, kind)
    page = _draw(HTML_FILE, odd, sc, tmp_path)
    payload = _payload(page)
    open_page(browser, page)
    assert severe_errors(browser) == []
    notes = [e.text for e in browser.find_elements("css selector", ".note")]
    assert notes == payload["notes"]
    if kind == "no_rows":
        assert browser.execute_script("return window.pushtrainReport.state().bodies.length") == 0
        return
    first = slide_to(browser, 0)
    assert len(first["bodies"]) == N + 1  # the first row is finite in every variant
    end = slide_to(browser, len(payload["rows"]) - 1)
    assert len(end["bodies"]) == (0 if kind == "diverged" else N + 1)
    assert severe_errors(browser) == []


def test_a_matplotlib_warning_while_saving_goes_to_the_log_not_the_user(tmp_path, caplog):
    """A warning matplotlib raises while laying out or saving a figure (as long legends of
    50 trailers did) is logged (run.log), never shown to the user; the picture is written."""
    import logging

    from pushtrain.report.common import new_figure, save

    fig = new_figure(3.0, 2.0)
    fig.add_subplot().plot([0, 1], [0, 1])
    real = fig.savefig

    def savefig(*args, **kwargs):
        warnings.warn("constrained_layout not applied", UserWarning, stacklevel=1)
        return real(*args, **kwargs)

    fig.savefig = savefig
    with caplog.at_level(logging.INFO, logger="pushtrain.report"), warnings.catch_warnings():
        warnings.simplefilter("error")
        path = save(fig, tmp_path / "x.png")
    assert path.is_file()
    assert "x.png: UserWarning: constrained_layout not applied" in caplog.text
