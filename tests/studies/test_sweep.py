"""Robustness sweeps (issue 7): spec, expansion, Dask vs serial, failures, resume, report, CLI.

Short scenarios: three trailers pushed 4 m along a straight line at 0.08 m/s (50 s, 10,000
steps) with a bias on joint 3; the Dask cluster (2 worker processes) is started once per module.
"""

from __future__ import annotations

import json
import logging
import math
import os
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner
from sweep_tasks import INJECTED, die_when_asked, install_failing_runner, restore_runner

from pushtrain.errors import SweepError
from pushtrain.mission.scenario import parse_scenario
from pushtrain.studies.sweep import run_sweep, sweep
from pushtrain.studies.sweep_results import read_results
from pushtrain.studies.sweep_runs import expand_runs, prepare_runs, run_key
from pushtrain.studies.sweep_spec import (
    METRICS,
    TIMING_COLUMNS,
    parse_path,
    parse_sweep_spec,
    set_path,
)
from pushtrain.studies.sweep_task import FmuRef, _materialize, run_task

BASE = {
    "name": "short_bias",
    "mission": {"kind": "scripted"},
    "train": {"n": 3},
    "start": {"x": 0.0, "y": 0.0, "theta_deg": 180.0},
    "reference": {"speed": 0.08, "segments": [{"kind": "line", "length": 4.0}]},
    "sensors": {"localize": "last_trailer", "joint_bias_deg": [0.0, 0.0, 0.0]},
    "sim": {"settle_time": 0.0, "goal_tolerance": 0.2},
}
BASE_TOML = """
name = "short_bias"
[mission]
kind = "scripted"
[train]
n = 3
[start]
x = 0.0
y = 0.0
theta_deg = 180.0
[reference]
speed = 0.08
segments = [{ kind = "line", length = 4.0 }]
[sensors]
localize = "last_trailer"
joint_bias_deg = [0.0, 0.0, 0.0]
[sim]
settle_time = 0.0
goal_tolerance = 0.2
"""
SPEC8 = {
    "name": "bias_gain",
    "steady_window": 5.0,
    "chunk_size": 2,
    "parameters": [
        {"path": "sensors.joint_bias_deg[2]", "values": [-6.0, -2.0, 2.0, 6.0]},
        {"path": "controller.k_y", "values": [4.0, 6.0]},
    ],
}
SPEC8_TOML = """
name = "bias_gain"
steady_window = 5.0
chunk_size = 2
[[parameters]]
path = "sensors.joint_bias_deg[2]"
values = [-6.0, -2.0, 2.0, 6.0]
[[parameters]]
path = "controller.k_y"
values = [4.0, 6.0]
"""
D = 0.52


@pytest.fixture(scope="module")
def client():
    from pushtrain.studies.sweep import local_client

    with local_client(2) as c:  # the cluster `pushtrain sweep` starts
        yield c


def test_our_cluster_runs_its_workers_without_the_profiler_and_fast_ticks(client):
    """Dask's sampling profiler and its 20 ms event-loop ticks take the interpreter lock from
    the co-simulation running in the worker (1.42 x the serial CPU time per run with them)."""
    def settings(dask_worker):
        import dask

        return ("profile" in dask_worker.periodic_callbacks,
                dask.config.get("distributed.admin.tick.interval"))

    assert set(client.run(settings).values()) == {(False, "1s")}
    assert len(client.scheduler_info()["workers"]) == 2


@pytest.fixture(scope="module")
def base():
    return parse_scenario(BASE, "base")


@pytest.fixture(scope="module")
def serial8(base, tmp_path_factory):
    out = tmp_path_factory.mktemp("serial8")
    return sweep(base, parse_sweep_spec(SPEC8), out, serial=True, plots=True)


def _table(rows):
    """Rows without the columns that measure time."""
    return [{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in rows]


# ----------------------------------------------------------------------------- spec and runs
@pytest.mark.parametrize("data, where, needle", [
    ({"parameters": [{"path": "train.n", "values": [1], "vals": 2}]}, "parameters[0].vals",
     "unknown key"),
    ({"parameters": [{"path": "train.n", "dist": "uniform", "low": 0, "high": 1}]},
     "parameters[0].dist", "monte_carlo"),
    ({"mode": "monte_carlo", "parameters": [{"path": "train.n", "values": [1, 2]}]}, "samples",
     "required"),
    ({"parameters": [{"path": "train..n", "values": [1]}]}, "parameters[0]", "not a field path"),
    ({"mode": "monte_carlo", "samples": 3,
      "parameters": [{"path": "controller.k_y", "dist": "uniform", "low": 2.0, "high": 1.0}]},
     "parameters[0]", "'low' < 'high'"),
    ({"parameters": [{"path": "controller.k_y", "values": [1.0], "range":
                      {"start": 0, "stop": 1, "num": 2}}]}, "parameters[0]", "exactly one"),
    ({"parameters": [{"path": "controller.k_y", "values": [{"a": 1}]}]},
     "parameters[0].values[0]", "valid"),
    ({"parameters": []}, "parameters", "at least 1"),
    ({"metrics": ["rms_lat"], "parameters": [{"path": "train.n", "values": [2]}]}, "metrics[0]",
     "rms_lat_m"),
])
def test_spec_errors_name_the_field(data, where, needle):
    with pytest.raises(SweepError) as err:
        parse_sweep_spec(data, "spec.toml")
    text = str(err.value)
    assert any(w == where for w, _, _ in err.value.errors), text
    assert needle in text, text


def test_paths_parse_get_and_set():
    assert parse_path("sensors.joint_bias_deg[2]") == ("sensors", "joint_bias_deg", 2)
    assert parse_path("events[0].distance") == ("events", 0, "distance")
    data = {"events": [{"distance": 1.0}], "train": {"n": 3}}
    set_path(data, "events[0].distance", -0.2)
    assert data["events"][0]["distance"] == -0.2
    with pytest.raises(KeyError, match=r"events\[1\]"):
        set_path(data, "events[1].distance", 0.0)
    with pytest.raises(KeyError, match="no such field"):
        set_path(data, "train.m", 0.0)


def test_grid_and_monte_carlo_expansion():
    grid = expand_runs(parse_sweep_spec(SPEC8))
    assert [r.params["sensors.joint_bias_deg[2]"] for r in grid[:3]] == [-6.0, -6.0, -2.0]
    assert [r.params["controller.k_y"] for r in grid[:3]] == [4.0, 6.0, 4.0]
    assert len({r.key for r in grid}) == 8
    assert grid[5].key == run_key(5, grid[5].params)
    mc = {"mode": "monte_carlo", "samples": 50, "seed": 7, "parameters": [
        {"path": "controller.k_y", "dist": "uniform", "low": 2.0, "high": 6.0},
        {"path": "sensors.joint_noise_deg", "dist": "normal", "mean": 0.5, "std": 0.1},
        {"path": "sensors.localize", "values": ["robot", "last_trailer"]}]}
    a = expand_runs(parse_sweep_spec(mc))
    b = expand_runs(parse_sweep_spec(mc))
    assert [r.params for r in a] == [r.params for r in b]
    k_y = [r.params["controller.k_y"] for r in a]
    assert all(2.0 <= v < 6.0 for v in k_y) and len(set(k_y)) == 50
    assert {r.params["sensors.localize"] for r in a} == {"robot", "last_trailer"}
    longer = expand_runs(parse_sweep_spec({**mc, "samples": 60}))
    assert [r.params for r in longer[:50]] == [r.params for r in a]
    other = expand_runs(parse_sweep_spec({**mc, "seed": 8}))
    assert [r.params for r in other] != [r.params for r in a]


def test_bad_combinations_are_reported_before_anything_runs(base, tmp_path):
    spec = parse_sweep_spec({"parameters": [{"path": "train.n", "values": [3, 5]}]})
    with pytest.raises(SweepError) as err:
        sweep(base, spec, tmp_path / "out", serial=True)
    assert "run 1 (train.n = 5): sensors.joint_bias_deg" in str(err.value)
    assert not (tmp_path / "out").exists()
    spec = parse_sweep_spec({"parameters": [{"path": "controller.k_yy", "values": [1.0]}]})
    with pytest.raises(SweepError, match=r"parameters\[0\]\.path.*no such field"):
        prepare_runs(base, spec)


# ------------------------------------------------------------------------------------ execution
def test_cluster_gives_the_same_numbers_as_serial(client, base, serial8, tmp_path):
    outcome = sweep(base, parse_sweep_spec(SPEC8), tmp_path, client=client, plots=False)
    assert outcome.complete and outcome.new == 8
    assert all(r["ok"] for r in outcome.rows)
    assert _table(outcome.rows) == _table(serial8.rows)
    assert _table(read_results(tmp_path / "results.csv")) == _table(serial8.rows)
    assert len(list((tmp_path / "chunks").glob("chunk-*.csv"))) == 4  # chunk_size = 2


def test_runs_batched_in_few_tasks_give_the_same_numbers(client, base, serial8, tmp_path,
                                                        monkeypatch):
    """Several runs per Dask task (one task per worker here: 4 runs each) give the rows of
    the serial loop, in the runs' order."""
    from pushtrain.studies import sweep as sweep_module

    monkeypatch.setattr(sweep_module, "TASKS_PER_WORKER", 1)
    submitted = []
    original = client.submit

    def counting_submit(*args, **kwargs):
        submitted.append(args[0].__name__)
        return original(*args, **kwargs)

    monkeypatch.setattr(client, "submit", counting_submit)
    outcome = sweep(base, parse_sweep_spec(SPEC8), tmp_path, client=client, plots=False)
    assert submitted == ["execute_batch"] * 2
    assert outcome.complete and outcome.new == 8
    assert _table(outcome.rows) == _table(serial8.rows)


def test_batches_cut_runs_in_order_into_enough_tasks():
    from pushtrain.studies.sweep import MAX_BATCH, TASKS_PER_WORKER, batches

    runs = list(range(1000))
    for workers in (1, 2, 7):
        cut = batches(runs, workers)
        assert [r for b in cut for r in b] == runs
        assert len(cut) >= TASKS_PER_WORKER * workers
        assert max(len(b) for b in cut) <= MAX_BATCH
    assert batches(list(range(5)), 2) == [[0], [1], [2], [3], [4]]  # small sweeps: one each
    assert batches([], 2) == []


def test_bias_offset_matches_the_closed_form(serial8):
    for row in serial8.rows:
        eps = math.radians(row["sensors.joint_bias_deg[2]"])
        expected = -math.sin(eps) / (D * row["controller.k_y"])  # last trailer localized
        assert row["predicted_steady_lat_m"] == pytest.approx(expected, rel=1e-9)
        assert row["steady_lat_m"] == pytest.approx(expected, rel=0.03), row




def test_failing_runs_are_recorded_and_the_sweep_finishes(client, base, tmp_path):
    spec = parse_sweep_spec({
        "overrides": {"sensors.joint_bias_deg[2]": 6.0, "sim.horizon": 50.0},
        "parameters": [{"path": "train.phi_max_deg", "values": [90.0, 1.0]},
                       # runs with settle_time 0.5 raise inside the workers
                       {"path": "sim.settle_time", "values": [0.0, 0.5]}]})
    client.run(install_failing_runner, 0.5)
    try:
        outcome = sweep(base, spec, tmp_path, client=client, plots=True)
    finally:
        client.run(restore_runner)
    by = {(r["train.phi_max_deg"], r["sim.settle_time"]): r for r in outcome.rows}
    assert outcome.complete and len(by) == 4
    assert by[(90.0, 0.0)]["ok"] and by[(90.0, 0.0)]["status"] == "goal_reached"
    assert by[(1.0, 0.0)]["status"] == "jackknifed" and "phi_max" in by[(1.0, 0.0)]["error"]
    for phi_max in (90.0, 1.0):
        row = by[(phi_max, 0.5)]
        assert row["status"] == "error" and INJECTED in row["error"]
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["ok"] == 1 and report["failed"] == 3
    assert {f["status"] for f in report["failures"]} == {"jackknifed", "error"}
    assert all(Path(p).is_file() for p in report["files"]["plots"])


def test_a_horizon_that_is_not_whole_steps_refuses_the_sweep_before_it_runs(base, tmp_path):
    spec = parse_sweep_spec({"parameters": [{"path": "sim.horizon", "values": [50.0, 50.0025]}]})
    with pytest.raises(SweepError, match="sim.horizon"):
        sweep(base, spec, tmp_path, serial=True, plots=False)
    assert not (tmp_path / "results.csv").exists()


def test_interrupted_sweep_resumes_to_the_same_table(base, serial8, tmp_path):
    spec = parse_sweep_spec(SPEC8)
    first = sweep(base, spec, tmp_path, serial=True, max_runs=3, plots=False)
    assert not first.complete and first.new == 3 and len(first.rows) == 3
    assert len(read_results(tmp_path / "results.csv")) == 3
    second = sweep(base, spec, tmp_path, serial=True, plots=False)
    assert second.complete and second.skipped == 3 and second.new == 5
    assert _table(second.rows) == _table(serial8.rows)
    changed = parse_sweep_spec({**SPEC8, "steady_window": 6.0})
    with pytest.raises(SweepError, match="different sweep"):
        sweep(base, changed, tmp_path, serial=True, plots=False)


def _chunk_rows(out: Path) -> list[dict]:
    return [r for p in sorted(out.glob("chunks/chunk-*.csv")) for r in read_results(p)]


def test_a_run_that_raises_is_an_error_row_with_nan_metrics_not_zeros(base, tmp_path):
    spec = parse_sweep_spec({"metrics": list(METRICS), "chunk_size": 1, "overrides": {
        "sim.settle_time": 0.5}, "parameters": [{"path": "controller.k_y", "values": [3.0, 4.0]}]})
    install_failing_runner(0.5)
    try:
        outcome = sweep(base, spec, tmp_path, serial=True, plots=False)
        resumed = sweep(base, spec, tmp_path, serial=True, plots=False)
    finally:
        restore_runner()
    assert outcome.complete and outcome.new == 2 and resumed.skipped == 2 and resumed.new == 0
    for where, rows in [("returned", outcome.rows), ("resumed", resumed.rows),
                        ("results.csv", read_results(tmp_path / "results.csv")),
                        ("chunks", _chunk_rows(tmp_path))]:
        assert len(rows) == 2, where
        for row in rows:
            assert row["status"] == "error" and row["ok"] is False, (where, row)
            assert INJECTED in row["error"], (where, row)
            numbers = {m: row[m] for m in METRICS}
            assert all(isinstance(v, float) and math.isnan(v) for v in numbers.values()), \
                (where, numbers)


@pytest.mark.slow
def test_a_resumed_sweep_runs_a_lost_run_again(base, tmp_path):
    import dask
    from distributed import Client, LocalCluster

    spec = parse_sweep_spec({"steady_window": 5.0, "parameters": [
        {"path": "controller.k_y", "values": [3.0, 4.0, 5.0]}]})
    runs, shared, manifest = prepare_runs(base, spec)
    kwargs = dict(steady_window=5.0, chunk_size=8, shared=shared, manifest=manifest)
    payload = runs[2].payload
    runs[2].payload = {**payload, "die": True}
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                         dashboard_address=":0", silence_logs=logging.ERROR) as cluster, \
            Client(cluster) as client:
        first = run_sweep(runs, die_when_asked, tmp_path, client=client, **kwargs)
    # a run that finished just before the worker died may not have been reported: lost as well
    statuses = [r["status"] for r in first.rows]
    assert statuses[2] == "lost" and set(statuses[:2]) <= {"goal_reached", "lost"}, statuses
    assert "KilledWorker" in first.rows[2]["error"]
    assert all(math.isnan(first.rows[2][m]) for m in spec.kept_metrics)
    n_lost = statuses.count("lost")
    assert not first.complete and first.remaining == n_lost
    assert [r["status"] for r in _chunk_rows(tmp_path)] == statuses  # the chunk holds the lost row

    runs[2].payload = payload
    second = run_sweep(runs, run_task, tmp_path, serial=True, **kwargs)
    assert second.complete and second.new == n_lost and second.skipped == 3 - n_lost
    assert [r["status"] for r in second.rows] == ["goal_reached"] * 3
    kept = [k for k, status in enumerate(statuses) if status != "lost"]
    assert [second.rows[k] for k in kept] == [first.rows[k] for k in kept]  # as written
    assert [r["status"] for r in read_results(tmp_path / "results.csv")] == ["goal_reached"] * 3


def test_fmu_bytes_are_written_on_a_worker_without_the_file(tmp_path, serial8):
    from pushtrain.fmu.build import build_fmu

    path = Path(build_fmu(3))
    import hashlib

    sha = hashlib.sha256(path.read_bytes()).hexdigest()
    ref = FmuRef(3, str(tmp_path / "elsewhere" / "TrailerTrain.fmu"), sha)
    local = _materialize(ref, {f"fmu-{sha}": path.read_bytes()})
    assert Path(local).read_bytes() == path.read_bytes()
    with pytest.raises(FileNotFoundError, match="not on this worker"):
        _materialize(ref, {})


def test_report_plots_exist_for_each_parameter_and_the_bias(serial8):
    names = sorted(Path(p).name for p in serial8.files["plots"])
    assert names == ["bias_offset.png", "sweep_controller_k_y.png",
                     "sweep_sensors_joint_bias_deg_2.png"]
    report = serial8.report
    assert report["success_rate"] == 1.0
    assert report["bias_prediction"]["max_deviation_over_largest_prediction"] < 0.03


def _fake_result(summary: dict, status: str = "goal_reached", e_lat=0.004, t_end: float = 20.0):
    """A stand-in for a co-simulation's Result (status, message, summary, data)."""
    from types import SimpleNamespace

    import numpy as np

    t = np.arange(0.0, t_end + 1e-9, 0.5)
    data = np.zeros(t.size, dtype=[("t", float), ("e_lat", float)])
    data["t"], data["e_lat"] = t, e_lat
    return SimpleNamespace(status=status, message="done", summary=summary, data=data)


def test_each_metric_comes_from_its_own_entry_of_the_summary():
    from pushtrain.studies.sweep_task import metrics_of

    summary = {"lateral_error_m": {"rms": 0.011, "max": 0.022, "final": 0.033},
               "heading_error_rad": {"rms": math.radians(1.5), "max": math.radians(2.5)},
               "max_abs_phi_deg": [10.0, 40.0, 20.0], "max_F_lat_ratio": [0.2, 0.7, None],
               "slip": [{"events": 2, "time_slipping_s": 0.5},
                        {"events": 1, "time_slipping_s": 0.25}],
               "t_final": 123.0, "steps": 24600, "wall_time_s": 4.5}
    e_lat = [0.1] * 21 + [0.044] * 20  # the last 10 s: 0.044 m
    row = metrics_of(_fake_result(summary, e_lat=e_lat), steady_window=9.5)
    assert row.pop("steady_lat_m") == pytest.approx(0.044)
    assert row.pop("rms_heading_deg") == pytest.approx(1.5)
    assert row.pop("max_heading_deg") == pytest.approx(2.5)
    assert row == {"status": "goal_reached", "message": "done", "rms_lat_m": 0.011,
                   "max_lat_m": 0.022, "final_lat_m": 0.033, "max_abs_phi_deg": 40.0,
                   "max_F_lat_ratio": 0.7, "slip_events": 3, "slip_time_s": 0.75,
                   "t_final": 123.0, "steps": 24600, "wall_time_s": 4.5}
    assert set(row) | {"steady_lat_m", "rms_heading_deg", "max_heading_deg"} \
        == set(METRICS) | {"status", "message"}


def test_seed_per_run_gives_each_run_the_spec_seed_plus_its_index(base):
    values = {"path": "controller.k_y", "values": [3.0, 4.0, 5.0]}
    runs, _, _ = prepare_runs(base, parse_sweep_spec(
        {"seed": 5, "seed_per_run": True, "parameters": [values]}))
    assert [r.payload["scenario"]["seed"] for r in runs] == [5, 6, 7]
    runs, _, _ = prepare_runs(base, parse_sweep_spec({"seed": 5, "parameters": [values]}))
    assert [r.payload["scenario"]["seed"] for r in runs] == [base.seed] * 3


def _fake_task(payload, shared):
    """Task function standing in for a co-simulation: instant, depends on the run's K_y."""
    k_y = payload["scenario"]["controller"]["k_y"]
    summary = {"lateral_error_m": {"rms": 0.01 / k_y, "max": 0.02 / k_y, "final": 0.0},
               "max_abs_phi_deg": [1.0], "max_F_lat_ratio": [0.1], "slip": [], "steps": 10,
               "wall_time_s": 0.0}
    return _fake_result(summary)


def _no_cluster(*args, **kwargs):
    raise AssertionError("a Dask cluster was started")


def test_cli_workers_0_runs_serially_and_max_runs_stops_then_resumes(tmp_path, monkeypatch):
    """--workers 0: no cluster, the runs in this process; --max-runs N: N runs now, the rest on
    the next call with the same --out."""
    import pushtrain.studies.sweep as library
    from pushtrain.cli.main import cli

    monkeypatch.setattr(library, "run_task", _fake_task)  # seen only by runs in this process
    monkeypatch.setattr(library, "local_client", _no_cluster)
    (tmp_path / "base.toml").write_text(BASE_TOML)
    (tmp_path / "spec.toml").write_text(SPEC8_TOML)
    out = tmp_path / "out"
    args = ["sweep", str(tmp_path / "base.toml"), "--spec", str(tmp_path / "spec.toml"),
            "--workers", "0", "--out", str(out), "--no-plots"]
    first = CliRunner().invoke(cli, [*args, "--max-runs", "3"])
    assert first.exit_code == 0, first.output
    assert "3 run now, 0 resumed" in first.stdout
    assert "incomplete: 5 run(s) still to do" in first.stdout
    assert len(read_results(out / "results.csv")) == 3
    second = CliRunner().invoke(cli, args)
    assert second.exit_code == 0, second.output
    assert "5 run now, 3 resumed from earlier chunks" in second.stdout
    rows = read_results(out / "results.csv")
    assert len(rows) == 8 and all(r["ok"] for r in rows)
    assert [r["rms_lat_m"] for r in rows] == pytest.approx([0.01 / k for k in (4, 6) * 4])


@pytest.mark.parametrize("what", ["notes", "run folder"])
def test_a_sweep_refuses_a_folder_of_other_files_and_leaves_it_alone(tmp_path, what):
    """A sweep's files must not mix with others: into a folder of notes, or a plan-and-run
    folder (replaced whole by the next run there, sweep results and all), it is exit 2 naming
    --out and the files, and nothing is written."""
    from pushtrain.cli.main import cli

    (tmp_path / "base.toml").write_text(BASE_TOML)
    (tmp_path / "spec.toml").write_text(SPEC8_TOML)
    out = tmp_path / "out"
    out.mkdir()
    names = {"notes.txt"} if what == "notes" else {".pushtrain-run", "summary.json"}
    for name in names:
        (out / name).write_text("mine")
    result = CliRunner().invoke(cli, ["sweep", str(tmp_path / "base.toml"), "--spec",
                                      str(tmp_path / "spec.toml"), "--workers", "0", "--out",
                                      str(out), "--no-plots"])
    assert result.exit_code == 2, result.output
    assert "holds other files" in result.output and str(out) in result.output
    assert {p.name for p in out.iterdir()} == names
    assert all((out / name).read_text() == "mine" for name in names)


# ------------------------------------------------------------------------------------------ CLI
@pytest.mark.parametrize("workers", ["0", "2"])
def test_cli_sweep(tmp_path, workers):
    from pushtrain.cli.main import cli

    (tmp_path / "base.toml").write_text(BASE_TOML)
    (tmp_path / "spec.toml").write_text(SPEC8_TOML)
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["sweep", str(tmp_path / "base.toml"), "--spec",
                                      str(tmp_path / "spec.toml"), "--workers", workers,
                                      "--out", str(out), "--no-plots"])
    assert result.exit_code == 0, result.output
    assert result.stdout.startswith(f"sweep bias_gain: 8 runs (grid 4 x 2) -> {out}\n")
    assert "success: 8/8" in result.output
    assert "steady[cm]" in result.output
    # stderr is not a terminal here: progress comes as lines, the last one when all are done
    assert "sweep: 8/8 new runs done, 0 failed" in result.stderr
    assert len(read_results(out / "results.csv")) == 8
    assert not list(out.glob("*.png"))


HUGE = {"name": "huge", "parameters": [
    {"path": "controller.k_y", "values": [3.0, 4.0, 5.0]},
    {"path": "controller.k_x", "range": {"start": 0.5, "stop": 2.0, "num": 100_000}}]}
HUGE_TOML = """
name = "huge"
[[parameters]]
path = "controller.k_y"
values = [3.0, 4.0, 5.0]
[[parameters]]
path = "controller.k_x"
range = { start = 0.5, stop = 2.0, num = 100000 }
"""


def _no_expansion(monkeypatch):
    """Make expanding runs fail, to show that a check happens before any run is made."""
    import pushtrain.studies.sweep_runs as sweep_runs

    def refuse(spec):
        raise AssertionError("the runs were expanded")

    monkeypatch.setattr(sweep_runs, "expand_runs", refuse)


def test_runs_are_counted_without_expanding_them(monkeypatch):
    from pushtrain.studies.sweep_spec import count_runs

    _no_expansion(monkeypatch)
    assert count_runs(parse_sweep_spec(HUGE)) == 300_000
    cube = {"parameters": [{"path": f"controller.k_{k}", "range": {"start": 0.0, "stop": 1.0,
                                                                  "num": 100_000}}
                           for k in ("x", "y", "theta")]}
    assert count_runs(parse_sweep_spec(cube)) == 10**15
    small = parse_sweep_spec(SPEC8)
    assert count_runs(small) == len(expand_runs(small)) == 8  # this module's own reference
    mc = {"mode": "monte_carlo", "samples": 250_000,
          "parameters": [{"path": "controller.k_y", "dist": "normal", "mean": 4.0, "std": 0.1}]}
    assert count_runs(parse_sweep_spec(mc)) == 250_000


def test_a_sweep_over_the_limit_is_refused_before_any_run_is_made(base, tmp_path, monkeypatch):
    _no_expansion(monkeypatch)
    with pytest.raises(SweepError) as err:
        sweep(base, parse_sweep_spec(HUGE), tmp_path / "out", serial=True)
    assert err.value.errors == [("runs (grid 3 x 100000)", 300_000, err.value.errors[0][2])]
    assert "limit of 100000 runs" in str(err.value)
    with pytest.raises(SweepError, match="limit of 7 runs"):
        sweep(base, parse_sweep_spec(SPEC8), tmp_path / "out", serial=True, max_total=7)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("spec_toml, options, count, limit", [
    (HUGE_TOML, [], "300000", "100000"),
    (SPEC8_TOML, ["--max-total", "5"], "8", "5"),
])
def test_cli_refuses_a_sweep_over_max_total_with_exit_2(tmp_path, monkeypatch, spec_toml,
                                                        options, count, limit):
    from pushtrain.cli.main import cli

    _no_expansion(monkeypatch)
    (tmp_path / "base.toml").write_text(BASE_TOML)
    (tmp_path / "spec.toml").write_text(spec_toml)
    result = CliRunner().invoke(cli, ["sweep", str(tmp_path / "base.toml"), "--spec",
                                      str(tmp_path / "spec.toml"), "--workers", "0",
                                      "--out", str(tmp_path / "out"), *options])
    assert result.exit_code == 2, result.output
    assert result.stdout.startswith(f"sweep {'huge' if count == '300000' else 'bias_gain'}: "
                                    f"{count} runs")
    assert f"= {count}: more than the limit of {limit} runs" in result.stderr
    assert not (tmp_path / "out").exists()


def test_progress_on_a_pipe_is_a_line_every_interval_and_one_at_the_end(capsys):
    from pushtrain.cli.sweep import _Progress

    now = [100.0]
    progress = _Progress(tty=False, interval=10.0, clock=lambda: now[0])
    progress.start(40)
    for done in range(1, 41):  # a run every 0.75 s: lines at 10.5 s, 21 s (10 s later), 30 s
        now[0] += 0.75
        progress.row({"ok": done % 10 != 0}, done, 40)
    progress.close()
    lines = capsys.readouterr().err.splitlines()
    assert lines == ["sweep: 14/40 new runs done, 1 failed, 10 s, about 20 s left",
                     "sweep: 28/40 new runs done, 2 failed, 21 s, about 9 s left",
                     "sweep: 40/40 new runs done, 4 failed, 30 s"]


SPEC16_TOML = """
name = "bias_gain_16"
steady_window = 5.0
chunk_size = 1
[overrides]
"reference.segments[0].length" = 8.0
[[parameters]]
path = "sensors.joint_bias_deg[2]"
values = [-6.0, -2.0, 2.0, 6.0]
[[parameters]]
path = "controller.k_y"
values = [3.0, 4.0, 5.0, 6.0]
"""


HOLD_AFTER_THE_FIRST_CHUNK = """
import sys, time
from pushtrain.studies import sweep_results
flush = sweep_results.ChunkWriter.flush
def flush_then_hold(self):
    flush(self)
    if self.written and not getattr(sweep_results, "held", False):
        sweep_results.held = True
        print("holding after " + self.written[0].name, file=sys.stderr, flush=True)
        while True:
            time.sleep(1.0)
sweep_results.ChunkWriter.flush = flush_then_hold
from pushtrain.cli.entry import pushtrain
sys.argv = ["pushtrain", *sys.argv[1:]]
pushtrain()
"""
"""The ``pushtrain`` console script, held (in the sweep's main process) once the first chunk
of rows is written, until a signal ends it: the Ctrl-C cannot come after the sweep's end."""


@pytest.mark.slow
def test_ctrl_c_stops_quietly_with_130_and_the_sweep_resumes(tmp_path):
    """Ctrl-C as a terminal sends it: SIGINT to the process group, the workers included.

    It is sent once the first chunk of rows is written (the process says so and holds there),
    not after a time: on a loaded machine the sweep finished before a timed Ctrl-C arrived."""
    import signal
    import subprocess
    import threading

    from pushtrain.cli.main import cli

    (tmp_path / "base.toml").write_text(BASE_TOML)
    (tmp_path / "spec.toml").write_text(SPEC16_TOML)
    out = tmp_path / "out"
    args = ["sweep", str(tmp_path / "base.toml"), "--spec", str(tmp_path / "spec.toml"),
            "--out", str(out), "--no-plots"]
    # SIGINT as a terminal's foreground process has it, however pytest was started (a job
    # put in the background by a shell without job control inherits it ignored)
    proc = subprocess.Popen([sys.executable, "-c", HOLD_AFTER_THE_FIRST_CHUNK, *args,
                             "--workers", "2"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    watchdog = threading.Timer(600.0, os.killpg, (proc.pid, signal.SIGKILL))  # a hang only
    watchdog.start()
    try:
        said = []
        for line in proc.stderr:  # until the process says it holds after the first chunk
            said.append(line)
            if line.startswith("holding after chunk-"):
                break
        assert said and said[-1].startswith("holding after chunk-"), "".join(said)
        assert list(out.glob("chunks/chunk-*.csv"))
        os.killpg(proc.pid, signal.SIGINT)
        stdout, stderr = proc.communicate()
    finally:
        watchdog.cancel()
    assert proc.returncode == 130, stdout + "".join(said) + stderr
    assert "Traceback" not in "".join(said) + stderr, stderr
    others = [line for line in stderr.splitlines() if not line.startswith("sweep: ")]
    assert len(others) == 1 and others[0].startswith("interrupted (Ctrl-C): "), stderr
    assert "run the same command with the same --out to resume" in others[0]
    kept = {r["key"]: r for p in sorted(out.glob("chunks/chunk-*.csv")) for r in read_results(p)}
    assert 1 <= len(kept) < 16

    result = CliRunner().invoke(cli, [*args, "--workers", "0"])
    assert result.exit_code == 0, result.output
    assert f"{16 - len(kept)} run now, {len(kept)} resumed from earlier chunks" in result.output
    assert "success: 16/16" in result.output
    rows = read_results(out / "results.csv")
    assert len(rows) == 16 and all(r["ok"] for r in rows)
    assert [r for r in rows if r["key"] in kept] == [kept[r["key"]] for r in rows
                                                     if r["key"] in kept]


@pytest.mark.slow
def test_sigterm_to_a_dask_sweep_is_exit_143_like_every_command(tmp_path):
    """SIGTERM (a batch scheduler, ``kill``) to the sweep's main process while it runs on its
    Dask cluster: exit 143 "terminated", the rows done kept (it was 130, Ctrl-C's code)."""
    import signal
    import subprocess
    import threading

    (tmp_path / "base.toml").write_text(BASE_TOML)
    (tmp_path / "spec.toml").write_text(SPEC16_TOML)
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-c", HOLD_AFTER_THE_FIRST_CHUNK, "sweep",
                             str(tmp_path / "base.toml"), "--spec", str(tmp_path / "spec.toml"),
                             "--out", str(out), "--no-plots", "--workers", "1"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    watchdog = threading.Timer(600.0, os.killpg, (proc.pid, signal.SIGKILL))  # a hang only
    watchdog.start()
    try:
        said = []
        for line in proc.stderr:
            said.append(line)
            if line.startswith("holding after chunk-"):
                break
        assert said and said[-1].startswith("holding after chunk-"), "".join(said)
        proc.send_signal(signal.SIGTERM)
        stdout, stderr = proc.communicate()
    finally:
        watchdog.cancel()
    assert proc.returncode == 143, stdout + "".join(said) + stderr
    assert "Traceback" not in stderr and "terminated (SIGTERM)" in stderr, stderr
    assert list(out.glob("chunks/chunk-*.csv"))


def test_cli_bad_spec_exits_2_naming_the_field(tmp_path):
    from pushtrain.cli.main import cli

    (tmp_path / "base.toml").write_text(BASE_TOML)
    (tmp_path / "spec.toml").write_text('[[parameters]]\npath = "controller.k_y"\nvalue = [1.0]\n')
    result = CliRunner().invoke(cli, ["sweep", str(tmp_path / "base.toml"), "--spec",
                                      str(tmp_path / "spec.toml"), "--workers", "0"])
    assert result.exit_code == 2, result.output
    assert "parameters[0].value" in result.output and "unknown key" in result.output


# ------------------------------------------------------------------------------------- examples
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_example_joint_bias_sweep_reproduces_fig14(tmp_path):
    outcome = sweep(EXAMPLES / "joint_bias_5deg.toml", EXAMPLES / "sweeps" / "joint_bias.toml",
                    tmp_path, serial=True, plots=False)
    assert outcome.complete and len(outcome.rows) == 11 and not outcome.failures
    for row in outcome.rows:
        eps = math.radians(row["sensors.joint_bias_deg[2]"])
        expected = -math.sin(eps) / (D * 4.0)  # K_y = 4, last trailer localized
        assert row["steady_lat_m"] == pytest.approx(expected, rel=0.02, abs=2e-4), row


def test_example_alternating_sign_spec_predicts_the_alternating_sum():
    from pushtrain.mission.scenario import load_scenario
    from pushtrain.studies.sweep_spec import load_sweep_spec

    spec = load_sweep_spec(EXAMPLES / "sweeps" / "alternating_sign.toml")
    runs, _, _ = prepare_runs(load_scenario(EXAMPLES / "joint_bias_5deg.toml"), spec)
    assert len(runs) == 27
    for run in runs:
        b = [run.params[f"sensors.joint_bias_deg[{k}]"] for k in range(3)]
        assert run.extras["eps_eff_deg"] == pytest.approx(b[2] - b[1] + b[0], abs=1e-12)
        assert run.payload["scenario"]["sensors"]["localize"] == "last_trailer"
        assert run.payload["scenario"]["reference"]["segments"][0]["length"] == 5.0


def test_plan_missions_are_planned_once_per_train_geometry_as_plain_data():
    from pushtrain.mission.scenario import load_scenario

    spec = parse_sweep_spec({"parameters": [{"path": "train.n", "values": [2, 3]},
                                            {"path": "controller.k_y", "values": [3.0, 4.0]}]})
    runs, _, _ = prepare_runs(load_scenario(EXAMPLES / "l_corridor.toml"), spec)
    texts = [json.dumps(r.payload["path"], sort_keys=True) for r in runs]  # plain data only
    assert texts[0] == texts[1] and texts[2] == texts[3] and texts[0] != texts[2]
    assert all(r.failure is None for r in runs)
    assert [r.payload["fmu"].n for r in runs] == [2, 2, 3, 3]

