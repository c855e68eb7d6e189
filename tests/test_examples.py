"""Every bundled example scenario runs end to end through the CLI, with every picture written
(``--plots all``; the GIF of one)."""

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from pushtrain.cli.main import cli
from pushtrain.files import RUN_MARKER

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
PLOTS = ("map.png", "inputs_joints.png", "tracking_error.png", "lateral_forces.png")


QUICK = {"l_corridor", "straight_push"}
"""The examples ``pytest -m "not slow"`` runs: the README's main job and the straight push (with
its GIF). The others are slow (the facility manoeuvres plan and co-simulate for long: docking
84 s simulated, the n = 10 corner 230 s); the whole suite runs them all."""


@pytest.mark.parametrize(
    "path", [pytest.param(p, marks=pytest.mark.slow) if p.stem not in QUICK else p
             for p in sorted(EXAMPLES.glob("*.toml"))], ids=lambda p: p.stem)
def test_example_runs_end_to_end(path, tmp_path):
    out = tmp_path / path.stem
    args = ["plan-and-run", str(path), "--out", str(out), "--plots", "all"]
    if path.stem == "straight_push":
        args.append("--gif")  # one GIF is enough to know the animation works
    result = CliRunner().invoke(cli, args)
    summary = json.loads((out / "summary.json").read_text())
    if summary["mission"] == "rotation":
        assert result.exit_code == 0, result.output
        assert summary["status"] == "completed"
        assert all(r is not None and r > 0 for r in summary["max_F_lat_ratio"])
    else:
        assert result.exit_code == 0, result.output
        assert summary["status"] == "goal_reached", summary["message"]
        _ends_at_the_goal(path, out)
    for name in PLOTS + ("report.html",):
        assert (out / name).stat().st_size > 10_000, name
    if path.stem == "straight_push":
        assert (out / "train.gif").stat().st_size > 10_000
    assert (out / "results.npz").is_file() and (out / "run.log").is_file()
    assert (out / RUN_MARKER).is_file()
    assert (out / "path.json").is_file() == (summary["mission"] == "plan")
    assert not list(out.glob(".*.part"))


def _ends_at_the_goal(path, out):
    """The co-simulated last trailer ends within the scenario's goal tolerance of its goal
    (docking: 2 cm and 1 deg), read from the recorded results."""
    import math

    import numpy as np

    from pushtrain.mission.scenario import load_scenario

    sc = load_scenario(path)
    if sc.mission.kind != "plan":
        return
    data = np.load(out / "results.npz")
    n = sc.train.n
    x, y, th = (float(data[f"{c}{n}"][-1]) for c in ("x", "y", "theta"))
    dist = math.hypot(x - sc.goal.x, y - sc.goal.y)
    head = abs(math.remainder(th - math.radians(sc.goal.theta_deg), 2 * math.pi))
    assert dist <= sc.sim.goal_tolerance + 1e-9, dist
    assert head <= math.radians(sc.sim.goal_heading_tolerance_deg) + 1e-9, math.degrees(head)
