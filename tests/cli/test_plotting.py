"""The plots and the GIF drawn in plot processes (pushtrain.cli.plotting): the same files as
drawn in the main process, a failure or a crash in a plot process is exit 1 naming the file
(never a hang or a traceback) with the results and the other files kept, and no plot process
outlives the command."""

import multiprocessing
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from pushtrain.cli import plotting
from pushtrain.cli.main import cli

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
PNGS = ("map.png", "inputs_joints.png", "tracking_error.png", "lateral_forces.png")
ALL = PNGS + ("train.gif",)
EVERYTHING = ("--plots", "all", "--gif")  # every picture (the default: report.html only)


def _short(tmp_path, horizon=1.0):
    """straight_push cut to ``horizon`` seconds (a fast run that misses the goal: exit 1)."""
    text = (EXAMPLES / "straight_push.toml").read_text()
    path = tmp_path / "short.toml"
    path.write_text(text + f"horizon = {horizon}\n")
    return str(path)


def _quick(tmp_path):
    """straight_push over 0.5 m (a fast run that reaches the goal: exit 0)."""
    text = (EXAMPLES / "straight_push.toml").read_text()
    for old, new in (("length = 11.0", "length = 0.5"), ("settle_time = 5.0", "settle_time = 2.0"),
                     # the slide within the 8.25 s run, and of nothing
                     ("t = 40.0", "t = 4.0"), ("distance = -0.15", "distance = 0.0")):
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / "quick.toml"
    path.write_text(text)
    return str(path)


def _invoke(args):
    result = CliRunner().invoke(cli, args)
    assert result.exception is None or isinstance(result.exception, SystemExit), result.output
    assert "Traceback" not in result.output, result.output
    return result


def _no_plot_process_left():
    assert multiprocessing.active_children() == []


def _complete(out: Path, names) -> None:
    """Every file in ``names`` is a whole image: PNGs decode, the GIF has all its frames."""
    for name in names:
        with Image.open(out / name) as image:
            image.load()
            if name.endswith(".gif"):
                assert image.n_frames > 1, name
                image.seek(image.n_frames - 1)
                image.load()
            else:
                assert image.size[0] > 300 and image.size[1] > 300, name
    assert not list(out.glob(".*.part*"))


def _failing(monkeypatch, bad_name: str, how):
    """Make drawing ``bad_name`` call ``how()`` (in whatever process draws it)."""
    from pushtrain.report import plots

    real = plots.plot_file

    def plot_file(name, *args, **kwargs):
        if name == bad_name:
            how()
        return real(name, *args, **kwargs)

    monkeypatch.setattr(plots, "plot_file", plot_file)


# ------------------------------------------------------------------------------- the files
@pytest.mark.slow
def test_the_plot_processes_write_the_same_files_as_the_main_process(tmp_path):
    """The files drawn in the plot processes equal, byte for byte, those drawn in the main
    process from the saved results (an independent route: report.plots.plot_all)."""
    import json
    from types import SimpleNamespace

    from pushtrain.cosim.result import load_results
    from pushtrain.mission.runner import geometry_of, world_of
    from pushtrain.mission.scenario import load_scenario
    from pushtrain.report import plots

    out = tmp_path / "out"
    result = _invoke(["run", _quick(tmp_path), *EVERYTHING, "--out", str(out)])
    assert result.exit_code == 0, result.output
    _complete(out, ALL)
    _no_plot_process_left()
    log = (out / "run.log").read_text()
    assert "plot process" in log and "peak resident memory" in log

    sc = load_scenario(_quick(tmp_path))
    saved = SimpleNamespace(data=load_results(out), n_trailers=sc.train.n,
                            status=json.loads((out / "summary.json").read_text())["status"])
    here = tmp_path / "here"
    t = sc.train
    plots.plot_all(saved, sc.train.n, here, world=world_of(sc), geometry=geometry_of(sc),
                   footprints={"robot": (t.robot_size.length, t.robot_size.width),
                               "trailer": (t.trailer_size.length, t.trailer_size.width)},
                   phi_max_deg=t.phi_max_deg)
    for name in ALL:
        assert (out / name).read_bytes() == (here / name).read_bytes(), name


@pytest.mark.slow
def test_drawing_in_the_main_process_when_no_process_can_be_forked(tmp_path, monkeypatch):
    def cannot_fork(*args, **kwargs):
        raise OSError("no fork here")

    monkeypatch.setattr(plotting, "PlotWorkers", cannot_fork)
    out = tmp_path / "out"
    result = _invoke(["run", _short(tmp_path), "--plots", "all", "--out", str(out)])
    assert result.exit_code == 1, result.output
    assert "cannot start plot processes" in result.output
    _complete(out, PNGS)
    assert not (out / "train.gif").exists()


def test_the_main_process_does_not_import_matplotlib(tmp_path):
    """The command's own process stays free of matplotlib (its memory is planning and
    co-simulation); the plot processes draw every file."""
    out = tmp_path / "out"
    code = ("import sys\n"
            "from pushtrain.cli.main import plan_and_run_main\n"
            f"sys.argv = ['plan-and-run', {_short(tmp_path, 0.3)!r}, '--out', {str(out)!r},"
            " '--plots', 'all', '--gif']\n"
            "try:\n"
            "    plan_and_run_main()\n"
            "except SystemExit as exc:\n"
            "    print('exit', exc.code, 'matplotlib' in sys.modules)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)
    assert done.stdout.strip().splitlines()[-1] == "exit 1 False", done.stdout + done.stderr
    _complete(out, ALL)


def test_by_default_a_run_writes_its_page_without_matplotlib_or_plot_processes(tmp_path):
    """The default pictures are report.html alone, written in the command's own process from
    the data (no matplotlib imported, no plot process started); the PNGs and the GIF come with
    --plots all and --gif, and --no-gif keeps working (it is the default)."""
    out = tmp_path / "out"
    code = ("import sys, multiprocessing\n"
            "from pushtrain.cli.main import plan_and_run_main\n"
            f"sys.argv = ['plan-and-run', {_quick(tmp_path)!r}, '--out', {str(out)!r},"
            " '--no-gif']\n"
            "try:\n"
            "    plan_and_run_main()\n"
            "except SystemExit as exc:\n"
            "    print('exit', exc.code, 'matplotlib' in sys.modules,"
            " len(multiprocessing.active_children()))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)
    assert done.stdout.strip().splitlines()[-1] == "exit 0 False 0", done.stdout + done.stderr
    pictures = sorted(p.name for p in out.iterdir() if p.suffix in (".png", ".gif", ".html"))
    assert pictures == ["report.html"]
    assert "report.html drawn" in (out / "run.log").read_text()
    assert "plot process" not in (out / "run.log").read_text()
    gif_only = tmp_path / "gif"
    result = _invoke(["run", _quick(tmp_path), "--gif", "--out", str(gif_only)])
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in gif_only.iterdir()
                  if p.suffix in (".png", ".gif", ".html")) == ["report.html", "train.gif"]
    _complete(gif_only, ["train.gif"])


@pytest.mark.parametrize("args, named", [
    (["--plots", "none", "--gif"], "--gif"),
    (["--no-plots", "--gif"], "--gif"),
    (["--no-plots", "--plots", "all"], "--no-plots"),
    (["--gif", "--no-gif"], "--gif"),
    (["--plots", "some"], "--plots"),
])
def test_contradicting_picture_options_are_exit_2_naming_them(tmp_path, args, named):
    out = tmp_path / "out"
    result = _invoke(["run", _quick(tmp_path), *args, "--out", str(out)])
    assert result.exit_code == 2, result.output
    assert named in result.output
    assert not out.exists()


def test_plots_none_draws_nothing(tmp_path):
    out = tmp_path / "out"
    result = _invoke(["run", _quick(tmp_path), "--plots", "none", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert not [p for p in out.iterdir() if p.suffix in (".png", ".gif", ".html")]
    assert (out / "results.npz").is_file()


# -------------------------------------------------------------------------------- failures
def test_a_file_that_cannot_be_drawn_is_exit_1_naming_it_and_the_rest_is_kept(tmp_path,
                                                                                monkeypatch):
    from pushtrain.errors import PlotError

    def boom():
        raise PlotError("boom in the map")

    _failing(monkeypatch, "map.png", boom)
    out = tmp_path / "out"
    result = _invoke(["run", _quick(tmp_path), *EVERYTHING, "--out", str(out)])
    assert result.exit_code == 1, result.output
    assert "could not draw map.png: PlotError: boom in the map" in result.output
    assert "status:" in result.output  # the summary is printed first
    _complete(out, [n for n in ALL if n != "map.png"])
    assert not (out / "map.png").exists()
    assert (out / "results.npz").is_file() and (out / "summary.json").is_file()
    log = (out / "run.log").read_text()
    assert "drawing map.png failed" in log and "Traceback" in log and "boom in the map" in log
    _no_plot_process_left()


@pytest.mark.parametrize("victim", ["train.gif", "lateral_forces.png"])
def test_a_plot_process_that_dies_is_exit_1_naming_the_file(tmp_path, monkeypatch, victim):
    """The process drawing ``victim`` is killed (the GIF is drawn by the first process, the
    last file by either): its file is reported, the other process draws the rest."""
    _failing(monkeypatch, victim, lambda: os.kill(os.getpid(), signal.SIGKILL))
    out = tmp_path / "out"
    start = time.monotonic()
    result = _invoke(["run", _quick(tmp_path), *EVERYTHING, "--out", str(out)])
    assert time.monotonic() - start < 60
    assert result.exit_code == 1, result.output
    assert f"could not draw {victim}: the plot process" in result.output
    assert (out / "results.npz").is_file()
    assert not (out / victim).exists()
    _complete(out, [n for n in ALL if n != victim and (out / n).exists()])
    _no_plot_process_left()


@pytest.mark.slow
def test_a_silent_plot_process_is_stopped(tmp_path, monkeypatch):
    monkeypatch.setattr(plotting, "SILENCE_LIMIT_S", 2.0)
    _failing(monkeypatch, "train.gif", lambda: time.sleep(120))
    out = tmp_path / "out"
    start = time.monotonic()
    result = _invoke(["run", _quick(tmp_path), *EVERYTHING, "--out", str(out)])
    assert time.monotonic() - start < 30  # the run takes a few seconds, the silence 2 s
    assert result.exit_code == 1, result.output
    assert "train.gif" in result.output and "no word from the plot processes" in result.output
    assert (out / "results.npz").is_file() and not (out / "train.gif").exists()
    assert not list(out.glob(".*.part*"))
    _no_plot_process_left()


def test_plot_processes_that_cannot_start_drawing_say_why(tmp_path, monkeypatch):
    def no_matplotlib(with_map):
        raise ImportError("No module named 'matplotlib'")

    monkeypatch.setattr(plotting, "_warm_up", no_matplotlib)
    out = tmp_path / "out"
    result = _invoke(["run", _quick(tmp_path), "--plots", "all", "--out", str(out)])
    assert result.exit_code == 1, result.output
    assert (f"could not draw {', '.join(PNGS)}: no plot process left (cannot draw: "
            "ImportError: "
            "No module named 'matplotlib')") in result.output
    assert (out / "results.npz").is_file() and (out / "report.html").is_file()
    _no_plot_process_left()


def test_a_failed_plan_stops_the_plot_processes(tmp_path):
    text = (EXAMPLES / "l_corridor.toml").read_text()
    blocked = text.replace(
        "free = [[0.0, 0.0], [9.0, 0.0], [9.0, 9.0], [7.0, 9.0], [7.0, 2.0], [0.0, 2.0]]",
        "free = [[0.0, 0.0], [9.0, 0.0], [9.0, 9.0], [7.0, 9.0], [7.0, 2.0], [0.0, 2.0]]\n"
        "obstacles = [[[7.0, 4.0], [9.0, 4.0], [9.0, 4.5], [7.0, 4.5]]]"
    ).replace("time_budget = 2.0", "time_budget = 0.3")
    assert blocked != text
    path = tmp_path / "blocked.toml"
    path.write_text(blocked)
    result = _invoke(["plan-and-run", str(path), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2, result.output  # no way joins start and goal: bad input
    assert "planning failed" in result.output
    _no_plot_process_left()


def test_bad_input_starts_no_plot_process(tmp_path, monkeypatch):
    started = []
    monkeypatch.setattr(plotting, "PlotWorkers", lambda *a, **k: started.append(1))
    bad = tmp_path / "bad.toml"
    bad.write_text((EXAMPLES / "straight_push.toml").read_text().replace(
        "[mission]", "[mission]\nunknown_key = 1"))
    result = _invoke(["run", str(bad), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2, result.output
    assert started == []


# ------------------------------------------------------------------------------- the pieces
def test_the_results_table_crosses_the_pipe_unchanged():
    """_send's raw bytes and _read_exactly rebuild the table exactly (NaN and all)."""
    context = multiprocessing.get_context("fork")
    mine, theirs = context.Pipe(duplex=True)
    table = np.zeros(70_001, dtype=[("t", float), ("x0", float), ("flag", np.int8)])
    table["t"] = np.linspace(0.0, 350.0, len(table))
    table["x0"] = np.sin(table["t"])
    table["x0"][::7] = np.nan
    table["flag"] = np.arange(len(table)) % 3
    import threading

    sender = threading.Thread(target=plotting._send,
                              args=([mine], {"rows": len(table), "dtype": table.dtype}, table))
    sender.start()
    header = theirs.recv()
    again = np.empty(header["rows"], dtype=header["dtype"])
    plotting._read_exactly(theirs.fileno(), memoryview(again.view(np.uint8)).cast("B"))
    sender.join()
    assert again.tobytes() == table.tobytes()
    mine.close()
    theirs.close()


def test_the_maps_module_imports_without_the_planner():
    """The plot processes unpickle the map: pushtrain.facility.free_space alone loads neither OMPL
    nor the lattice search."""
    code = ("import sys, pushtrain.facility.free_space\n"
            "print(sorted(m for m in ('ompl', 'pushtrain.planner.lattice', "
            "'pushtrain.planner.planner') if m in sys.modules))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["[]"], done.stdout


@pytest.mark.slow
def test_plot_processes_0_draws_here_the_same_files(tmp_path, monkeypatch):
    """--plot-processes 0 starts no plot process (the least memory) and writes the files the
    plot processes write; a count outside 0..2 is exit 2 naming the option."""
    forked = _invoke(["run", _quick(tmp_path), *EVERYTHING, "--out",
                      str(tmp_path / "forked")])
    assert forked.exit_code == 0, forked.output

    def no_workers(*args, **kwargs):
        raise AssertionError("a plot process was started")

    monkeypatch.setattr(plotting, "PlotWorkers", no_workers)
    here = tmp_path / "here"
    result = _invoke(["run", _quick(tmp_path), *EVERYTHING, "--plot-processes", "0", "--out",
                      str(here)])
    assert result.exit_code == 0, result.output
    _complete(here, ALL)
    for name in ALL:
        assert (here / name).read_bytes() == (tmp_path / "forked" / name).read_bytes(), name
    bad = _invoke(["run", _quick(tmp_path), "--plot-processes", "3", "--out",
                   str(tmp_path / "bad")])
    assert bad.exit_code == 2 and "--plot-processes" in bad.output and "0<=x<=2" in bad.output
