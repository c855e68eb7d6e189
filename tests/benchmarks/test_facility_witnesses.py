"""The facility benchmark's witnesses: every mission it calls feasible has a stored last-trailer
path that ``pushtrain run SCENARIO --path WITNESS`` co-simulates to the goal (the FMU, the
controller and the map check; no planner involved)."""

import json
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from pushtrain.cli.main import cli

BENCH = Path(__file__).resolve().parents[2] / "benchmarks"
sys.path.insert(0, str(BENCH))

import bench_facility  # noqa: E402

MISSIONS = bench_facility.load_missions()
WITNESSED = [m for m in MISSIONS if bench_facility.witness_of(m).exists()]


def test_every_witness_belongs_to_a_mission_and_every_impossible_one_has_a_reason():
    """A witness file names a mission of missions.toml (a renamed mission would leave its
    witness behind, and the benchmark would count it as unresolved); an "impossible" mission
    has no witness and a reason."""
    names = {bench_facility.witness_of(m).name for m in MISSIONS}
    stored = {p.name for p in bench_facility.WITNESSES.glob("*.path.json")}
    assert stored <= names, sorted(stored - names)
    assert len(WITNESSED) >= 30
    impossible = bench_facility.impossible_reasons()
    keys = {m["key"] for m in MISSIONS}
    for key, reason in impossible.items():
        assert key in keys and reason["reason"].strip() and reason["width"] >= 0.0, key
        assert not bench_facility.witness_of({"key": key}).exists(), key


@pytest.mark.slow
@pytest.mark.parametrize("mission", WITNESSED, ids=lambda m: m["key"])
def test_the_witness_co_simulates_to_the_goal(mission, tmp_path):
    scenario = tmp_path / "scenario.toml"
    scenario.write_text(bench_facility.scenario_toml(mission))
    out = tmp_path / "run"
    result = CliRunner().invoke(cli, ["run", str(scenario), "--path",
                                      str(bench_facility.witness_of(mission)), "--out", str(out),
                                      "--no-plots"])
    summary = json.loads((out / "summary.json").read_text())
    assert result.exit_code == 0, result.output
    assert summary["status"] == "goal_reached", summary["message"]
