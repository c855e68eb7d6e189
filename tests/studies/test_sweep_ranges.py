"""Tests that catch single-line bugs planted in the sweep (issue #29): a range that drops its
last value, and a table that fills ``error`` for runs that succeeded."""

from __future__ import annotations

import pytest

from pushtrain.mission.scenario import parse_scenario
from pushtrain.studies.sweep import sweep
from pushtrain.studies.sweep_results import finish_row, read_results
from pushtrain.studies.sweep_runs import SweepRun, expand_runs
from pushtrain.studies.sweep_spec import parse_sweep_spec


def test_a_range_includes_both_ends():
    """examples/sweeps/joint_bias.toml's range: -10 to 10 deg in 11 values, 2 deg apart."""
    spec = parse_sweep_spec({"parameters": [{"path": "sensors.joint_bias_deg[2]",
                                             "range": {"start": -10.0, "stop": 10.0, "num": 11}}]})
    values = spec.parameters[0].grid_values()
    assert values == pytest.approx([-10.0, -8.0, -6.0, -4.0, -2.0, 0.0, 2.0, 4.0, 6.0, 8.0, 10.0],
                                   abs=1e-12)
    runs = expand_runs(spec)
    assert [r.params["sensors.joint_bias_deg[2]"] for r in runs][-1] == 10.0
    # two values: the ends themselves
    two = parse_sweep_spec({"parameters": [{"path": "controller.k_y",
                                            "range": {"start": 2.0, "stop": 6.0, "num": 2}}]})
    assert two.parameters[0].grid_values() == [2.0, 6.0]


def test_a_row_has_an_error_only_when_its_run_failed():
    run = SweepRun(0, "k0", {"controller.k_y": 4.0})
    ok = finish_row({"status": "goal_reached", "message": "goal reached at t = 50.000 s"}, run)
    assert ok["ok"] is True and ok["error"] == ""
    done = finish_row({"status": "completed", "message": "ran the full horizon of 5.000 s"}, run)
    assert done["ok"] is True and done["error"] == ""
    failed = finish_row({"status": "jackknifed", "message": "jackknife at t = 3.000 s"}, run)
    assert failed["ok"] is False and failed["error"] == "jackknife at t = 3.000 s"


BASE = {"name": "short", "mission": {"kind": "scripted"}, "train": {"n": 3},
        "start": {"x": 0.0, "y": 0.0, "theta_deg": 180.0},
        "reference": {"speed": 0.08, "segments": [{"kind": "line", "length": 1.0}]},
        "sim": {"settle_time": 0.0, "goal_tolerance": 0.2}}


def test_the_results_table_leaves_error_empty_for_successful_runs(tmp_path):
    """A real (serial) sweep of two runs: the one that reaches its goal has no error in
    results.csv, the one stopped by a 1 s horizon has the run's message."""
    spec = parse_sweep_spec({"parameters": [{"path": "sim.step", "values": [0.005]}],
                             "overrides": {}})
    ok_base = parse_scenario(BASE, "base")
    outcome = sweep(ok_base, spec, tmp_path / "ok", serial=True, plots=False)
    short = parse_scenario({**BASE, "sim": {**BASE["sim"], "horizon": 1.0}}, "base")
    cut = sweep(short, spec, tmp_path / "cut", serial=True, plots=False)
    (good,) = read_results(tmp_path / "ok" / "results.csv")
    (bad,) = read_results(tmp_path / "cut" / "results.csv")
    assert good["status"] == "goal_reached" and good["ok"] is True
    assert good["error"] == "", good["error"]
    assert bad["status"] == "time_limit" and bad["ok"] is False
    assert "time limit" in bad["error"]
    assert outcome.rows[0]["error"] == "" and cut.rows[0]["error"] == bad["error"]
