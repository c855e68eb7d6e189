"""The CLI's run folders, logging and hardening: one run per folder, exit 2 for output folders
and files that cannot be used, exit 1 when the co-simulation misses the goal, handlers that do
not pile up, heavy libraries imported only when needed."""

import json
import logging
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from pushtrain.cli.main import cli
from pushtrain.files import RUN_MARKER

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
BLOCKED_MAP = ("free = [[0.0, 0.0], [9.0, 0.0], [9.0, 9.0], [7.0, 9.0], [7.0, 2.0], [0.0, 2.0]]\n"
               "obstacles = [[[7.0, 4.0], [9.0, 4.0], [9.0, 4.5], [7.0, 4.5]]]")
L_FREE = "free = [[0.0, 0.0], [9.0, 0.0], [9.0, 9.0], [7.0, 9.0], [7.0, 2.0], [0.0, 2.0]]"


def _scenario(tmp_path, example, name, *, append="", replace=()):
    text = (EXAMPLES / f"{example}.toml").read_text()
    for old, new in replace:
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / f"{name}.toml"
    path.write_text(text.replace(f'name = "{example}"', f'name = "{name}"') + append)
    return str(path)


def _short(tmp_path, name="short", horizon=0.5):
    """straight_push with a horizon far too short to reach the goal (a fast run, exit 1)."""
    return _scenario(tmp_path, "straight_push", name, append=f"horizon = {horizon}\n")


def _no_traceback(result):
    assert result.exception is None or isinstance(result.exception, SystemExit), result.output
    assert "Traceback" not in result.output, result.output


def _invoke(args):
    result = CliRunner().invoke(cli, args)
    _no_traceback(result)
    return result


# ------------------------------------------------------------------------------ output folders
@pytest.mark.parametrize("command", ["run", "plan-and-run"])
def test_out_under_a_file_exits_2_naming_the_file(tmp_path, command):
    (tmp_path / "some_file").write_text("x")
    result = _invoke([command, _short(tmp_path), "--no-plots", "--out",
                      str(tmp_path / "some_file" / "sub")])
    assert result.exit_code == 2, result.output
    assert "--out" in result.output and "some_file' is a file" in result.output
    assert (tmp_path / "some_file").read_text() == "x"


def test_out_where_no_folder_can_be_made_exits_2(tmp_path):
    result = _invoke(["run", _short(tmp_path), "--no-plots", "--out", "/proc/pushtrain-x"])
    assert result.exit_code == 2, result.output
    assert "/proc/pushtrain-x" in result.output and "allowed" in result.output


def test_out_that_is_a_file_exits_2(tmp_path):
    target = tmp_path / "taken"
    target.write_text("x")
    result = _invoke(["slip-study", "--trailers", "1", "--alphas", "5", "--out", str(target)])
    assert result.exit_code == 2, result.output
    assert "taken" in result.output


def test_a_folder_of_other_files_is_refused_and_kept(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("precious")
    result = _invoke(["run", _short(tmp_path), "--no-plots", "--out", str(out)])
    assert result.exit_code == 2, result.output
    assert RUN_MARKER in result.output and "not a pushtrain run folder" in result.output
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]


def test_a_failed_plan_after_a_successful_run_leaves_only_the_failed_run(tmp_path):
    out = tmp_path / "out"
    ok = _scenario(tmp_path, "straight_push", "first_run",
                   replace=[("length = 11.0", "length = 0.5"),
                            ("settle_time = 5.0", "settle_time = 2.0"),
                            # the slide within the 8.25 s run, and of nothing
                            ("t = 40.0", "t = 4.0"), ("distance = -0.15", "distance = 0.0")])
    first = _invoke(["plan-and-run", ok, "--no-plots", "--out", str(out)])
    assert first.exit_code == 0, first.output
    assert (out / "results.npz").is_file()
    blocked = _scenario(tmp_path, "l_corridor", "second_run",
                        replace=[(L_FREE, BLOCKED_MAP),
                                 ("time_budget = 2.0", "time_budget = 0.3")])
    second = _invoke(["plan-and-run", blocked, "--no-plots", "--out", str(out)])
    assert second.exit_code == 2, second.output  # no way joins start and goal: bad input
    assert "planning failed" in second.output and "impossible here" in second.output
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [RUN_MARKER, "planning_failure.png", "report.html", "run.log", "scenario.json",
         "summary.json"])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "planning_failed" and summary["scenario"] == "second_run"
    assert summary["exit_code"] == 2 and summary["message"].startswith("planning failed")
    assert json.loads((out / "scenario.json").read_text())["name"] == "second_run"
    assert "first_run" not in (out / "run.log").read_text()
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []


def test_a_bad_scenario_is_refused_before_the_previous_run_is_touched(tmp_path):
    """A slide event with slip_mode 1 is refused by the scenario check: exit 2 naming both
    fields, and the previous run stays whole (nothing was started)."""
    out = tmp_path / "out"
    assert _invoke(["run", _short(tmp_path), "--no-plots", "--out", str(out)]).exit_code == 1
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    bad = _scenario(tmp_path, "straight_push", "late",
                    append="horizon = 0.5\n[fmu]\nslip_mode = 1\n")
    result = _invoke(["run", bad, "--no-plots", "--out", str(out)])
    assert result.exit_code == 2, result.output
    assert "events[0].type" in result.output and "slip_mode" in result.output
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_late_bad_input_replaces_the_previous_run_and_says_invalid(tmp_path, monkeypatch):
    """An input error that only the co-simulation finds (injected here: the scenario check
    leaves none that we know of) gives exit 2, and the folder holds the refused run only."""
    from pushtrain.errors import CosimInputError
    from pushtrain.mission import runner

    out = tmp_path / "out"
    assert _invoke(["run", _short(tmp_path), "--no-plots", "--out", str(out)]).exit_code == 1

    def refuse(*args, **kwargs):
        raise CosimInputError("plant.slip_mode = 1: injected refusal of the co-simulation")

    monkeypatch.setattr(runner, "run_scenario", refuse)
    late = _scenario(tmp_path, "straight_push", "late", append="horizon = 0.5\n")
    result = _invoke(["run", late, "--no-plots", "--out", str(out)])
    assert result.exit_code == 2, result.output
    assert "injected refusal" in result.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "invalid" and summary["scenario"] == "late"
    assert not (out / "results.npz").exists()


# ------------------------------------------------------------------------------- exit codes
def test_a_planned_run_that_misses_the_goal_exits_1(tmp_path):
    """Planning succeeds, the co-simulation stops at a 5 s horizon far from the goal."""
    path = _scenario(tmp_path, "l_corridor", "short_l",
                     append="\n[sim]\nhorizon = 5.0\n")
    out = tmp_path / "out"
    result = _invoke(["plan-and-run", path, "--no-plots", "--out", str(out)])
    assert result.exit_code == 1, result.output
    assert "planning failed" not in result.output and "path:" in result.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] not in ("goal_reached", "completed"), summary["status"]
    assert (out / "path.json").is_file() and (out / "results.npz").is_file()


def test_a_scripted_run_that_collides_exits_1(tmp_path):
    """The reference runs the train into the end wall of the corridor."""
    path = _scenario(tmp_path, "straight_push", "wall",
                     replace=[("[14.0, -1.0], [14.0, 1.0]", "[1.6, -1.0], [1.6, 1.0]")],
                     append="horizon = 12.0\n")
    out = tmp_path / "out"
    result = _invoke(["run", path, "--no-plots", "--out", str(out)])
    assert result.exit_code == 1, result.output
    assert json.loads((out / "summary.json").read_text())["status"] == "collision"


@pytest.mark.parametrize("exit_code, status", [(2, "invalid"), (1, "failed")])
def test_a_command_error_inside_a_run_folder_is_recorded_with_its_exit_code(tmp_path, exit_code,
                                                                             status):
    """A click error raised while the run folder is open keeps its exit code, and summary.json
    says why the run ended: bad input found late (2) is ``invalid``, anything else ``failed``."""
    import click

    from pushtrain.cli.common import BadInput
    from pushtrain.cli.rundir import run_folder

    error = BadInput("refused late") if exit_code == 2 else click.ClickException("broke")
    error.exit_code = exit_code
    out = tmp_path / "out"
    with pytest.raises(click.ClickException) as info:
        with run_folder(str(out), "late"):
            raise error
    assert info.value.exit_code == exit_code
    summary = json.loads((out / "summary.json").read_text())
    assert summary == {"status": status, "message": error.format_message(),
                       "exit_code": exit_code}


# ----------------------------------------------------------------------------------- files
def test_run_with_path_writes_path_json(tmp_path):
    path_file = tmp_path / "saved.json"
    result = _invoke(["plan", str(EXAMPLES / "l_corridor.toml"), "--out", str(path_file)])
    assert result.exit_code == 0, result.output
    short = _scenario(tmp_path, "l_corridor", "replay", append="\n[sim]\nhorizon = 0.5\n")
    out = tmp_path / "out"
    result = _invoke(["run", short, "--path", str(path_file), "--no-plots", "--out", str(out)])
    assert result.exit_code == 1, result.output  # 0.5 s is too short to reach the goal
    assert json.loads((out / "path.json").read_text()) == json.loads(path_file.read_text())


@pytest.mark.parametrize("command", ["validate", "plan-and-run", "analyze"])
def test_a_scenario_that_is_not_utf8_exits_2(tmp_path, command):
    path = tmp_path / "latin1.toml"
    path.write_bytes('description = "caf\u00e9"\n[train]\nn = 3\n'.encode("latin-1"))
    result = _invoke([command, str(path)])
    assert result.exit_code == 2, result.output
    assert "UTF-8" in result.output and "line 1" in result.output and "\\xe9" in result.output


@pytest.mark.parametrize("option", ["--out", "--plot"])
def test_plan_output_files_that_cannot_be_written_exit_2(tmp_path, option):
    (tmp_path / "some_file").write_text("x")
    target = str(tmp_path / "some_file" / "path.out")
    result = _invoke(["plan", str(EXAMPLES / "l_corridor.toml"), option, target])
    assert result.exit_code == 2, result.output
    assert option in result.output and "cannot be written" in result.output


def test_build_fmu_into_a_folder_that_cannot_be_made_exits_2(tmp_path):
    (tmp_path / "some_file").write_text("x")
    result = _invoke(["build-fmu", "-n", "1", "-o", str(tmp_path / "some_file" / "x.fmu")])
    assert result.exit_code == 2, result.output
    assert "--out" in result.output


# ----------------------------------------------------------------------------- the process
def test_calls_leave_the_loggers_handlers_and_level_as_they_were(tmp_path):
    logger = logging.getLogger("pushtrain")
    before = (list(logger.handlers), logger.level)
    short = _short(tmp_path)
    for _ in range(3):
        run = _invoke(["-v", "run", short, "--no-plots", "--out", str(tmp_path / "o")])
        assert run.exit_code == 1
        assert _invoke(["validate", short]).exit_code == 0
        assert _invoke(["plan-and-run", str(tmp_path / "missing.toml")]).exit_code == 2
    assert (list(logger.handlers), logger.level) == before
    log_text = (tmp_path / "o" / "run.log").read_text()
    assert log_text.count("run folder") == 1, "run.log holds one run, logged once"


def test_the_console_script_leaves_no_handler_behind(monkeypatch, tmp_path):
    from pushtrain.cli.main import plan_and_run_main

    logger = logging.getLogger("pushtrain")
    before = list(logger.handlers)
    monkeypatch.setattr(sys, "argv", ["plan-and-run", str(tmp_path / "missing.toml")])
    with pytest.raises(SystemExit) as exc:
        plan_and_run_main()
    assert exc.value.code == 2
    assert logger.handlers == before


def test_importing_the_cli_loads_no_heavy_library():
    heavy = ("distributed", "dask", "ompl", "matplotlib")
    code = (f"import sys, pushtrain.cli.main; print([m for m in {heavy!r} if m in sys.modules])")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]", done.stdout


def test_every_command_module_is_registered():
    import pkgutil

    import pushtrain.cli.commands as commands

    modules = {m.name.replace("_", "-") for m in pkgutil.iter_modules(commands.__path__)}
    assert modules == set(cli.commands) - {"sweep"}


# ------------------------------------------------------------------------------ result files
def test_results_npz_is_the_table_and_csv_comes_only_with_the_option(tmp_path):
    import numpy as np

    from pushtrain.cosim.master import _columns
    from pushtrain.cosim.result import load_results

    plain, with_csv = tmp_path / "plain", tmp_path / "with_csv"
    scenario = _short(tmp_path, horizon=0.2)
    assert _invoke(["run", scenario, "--no-plots", "--out", str(plain)]).exit_code == 1
    result = _invoke(["run", scenario, "--no-plots", "--csv", "--out", str(with_csv)])
    assert result.exit_code == 1, result.output
    assert not (plain / "results.csv").exists() and (with_csv / "results.csv").is_file()
    with np.load(plain / "results.npz") as z:
        assert list(z.files) == _columns(3)
        assert len(z["t"]) == 41 and z["t"][-1] == pytest.approx(0.2)
    table = load_results(plain)
    assert table.dtype.names == tuple(_columns(3))
    again = load_results(with_csv)
    for name in table.dtype.names:  # the same run twice (no noise): the same numbers
        assert np.array_equal(table[name], again[name], equal_nan=True), name
    text = np.genfromtxt(with_csv / "results.csv", delimiter=",", names=True)
    assert text.dtype.names == table.dtype.names
    for name in table.dtype.names:  # the CSV holds 10 significant digits
        assert np.allclose(text[name], table[name], rtol=1e-9, atol=1e-12, equal_nan=True), name


def test_progress_goes_to_a_pipe_one_line_per_phase(tmp_path):
    """Piped (not a terminal), each phase is announced as it starts and the last line says
    how long each took."""
    script = Path(sys.executable).with_name("plan-and-run")
    out = tmp_path / "out"
    done = subprocess.run([str(script), _short(tmp_path, horizon=0.2), "--plots", "all",
                           "--out", str(out)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 1, done.stderr
    lines = [line for line in done.stderr.splitlines() if line.startswith("[")]
    assert [line.split("] ", 1)[1] for line in lines[:-1]] == [
        "co-simulating ...", "saving the results ...", "writing report.html ...",
        "plotting map.png, inputs_joints.png, tracking_error.png, lateral_forces.png ..."]
    stamps = [float(line[1:].split("s]")[0]) for line in lines]
    assert stamps == sorted(stamps)
    phases = lines[-1].split("] done: ", 1)[1].split(", ")
    assert [p.rsplit(" ", 2)[0] for p in phases] == ["co-simulate", "save", "page", "plots"]
    assert all(float(p.rsplit(" ", 2)[1]) >= 0 for p in phases)
    assert "status:" in done.stdout and "status:" not in done.stderr
    assert (out / "map.png").is_file() and not (out / "train.gif").exists()
    assert "phase times: co-simulate" in (out / "run.log").read_text()


def test_load_results_reads_a_folder_with_only_a_csv(tmp_path):
    import numpy as np

    from pushtrain.cosim.result import load_results

    (tmp_path / "results.csv").write_text("t,x0,e_lat\n0,1.5,nan\n0.005,1.25,-0.001\n")
    table = load_results(tmp_path)
    assert table.dtype.names == ("t", "x0", "e_lat")
    assert np.array_equal(table["x0"], [1.5, 1.25])
    assert np.isnan(table["e_lat"][0])
    np.savez(tmp_path / "results.npz", t=np.array([7.0]), x0=np.array([8.0]))
    assert load_results(tmp_path).dtype.names == ("t", "x0")  # the NPZ comes first
    with pytest.raises(FileNotFoundError, match="results.npz"):
        load_results(tmp_path / "empty")


def test_save_results_keeps_every_bit_and_writes_atomically(tmp_path, monkeypatch):
    import numpy as np

    from pushtrain.cosim import result as results
    from pushtrain.cosim.result import Result

    rng = np.random.default_rng(3)
    names = ["t", "x0", "phi1", "slipping1"]
    data = np.empty(1000, dtype=[(k, "f8") for k in names])
    for k in names:
        data[k] = rng.normal(size=1000) * 10.0 ** rng.integers(-300, 300, size=1000)
    data["phi1"][:3] = [-0.0, np.nan, np.inf]
    result = Result("completed", "", data, {"status": "completed", "steps": 999}, 1)
    files = result.save(tmp_path / "run")
    assert sorted(files) == ["npz", "summary"] and result.files == files
    with np.load(files["npz"]) as z:
        assert list(z.files) == names
        for k in names:
            assert z[k].tobytes() == data[k].tobytes(), k  # bit for bit, -0.0 and NaN included
    assert json.loads(Path(files["summary"]).read_text()) == result.summary

    def full_disk(partial, table):
        Path(partial).write_bytes(b"PK partial")
        raise OSError("disk full")

    monkeypatch.setattr(results, "write_npz", full_disk)
    with pytest.raises(OSError, match="disk full"):
        result.save(tmp_path / "run", csv=True)
    with np.load(files["npz"]) as z:  # the previous file is intact, no partial file is left
        assert z["t"].tobytes() == data["t"].tobytes()
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == ["results.npz",
                                                                    "summary.json"]


def test_the_first_fmu_build_is_a_phase_of_its_own(tmp_path, monkeypatch):
    """With an empty FMU cache the run announces the build (a few seconds) before
    co-simulating, and times it as its own phase; the next run, cached, does not."""
    monkeypatch.setenv("PUSHTRAIN_CACHE", str(tmp_path / "cache"))
    short = _short(tmp_path)
    first = _invoke(["run", short, "--no-plots", "--out", str(tmp_path / "a")])
    assert first.exit_code == 1, first.output  # the short horizon misses the goal
    assert "building the FMU (FMI 2.0; first use" in first.output
    assert "build FMU " in first.output  # in the closing "done: ..." line of phase times
    assert list((tmp_path / "cache" / "fmu").glob("*.fmu"))
    again = _invoke(["run", short, "--no-plots", "--out", str(tmp_path / "b")])
    assert again.exit_code == 1 and "building the FMU" not in again.output
