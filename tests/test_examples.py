"""Every bundled example scenario runs end to end through the CLI, with plots written."""

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from pushtrain.cli.main import cli
from pushtrain.files import RUN_MARKER

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
PLOTS = ("map.png", "inputs_joints.png", "tracking_error.png", "lateral_forces.png")


@pytest.mark.parametrize("path", sorted(EXAMPLES.glob("*.toml")), ids=lambda p: p.stem)
def test_example_runs_end_to_end(path, tmp_path):
    out = tmp_path / path.stem
    args = ["plan-and-run", str(path), "--out", str(out)]
    if path.stem != "straight_push":
        args.append("--no-gif")  # one GIF is enough to know the animation works
    result = CliRunner().invoke(cli, args)
    summary = json.loads((out / "summary.json").read_text())
    if summary["mission"] == "rotation":
        assert result.exit_code == 0, result.output
        assert summary["status"] == "completed"
        assert all(r is not None and r > 0 for r in summary["max_F_lat_ratio"])
    else:
        assert result.exit_code == 0, result.output
        assert summary["status"] == "goal_reached", summary["message"]
    for name in PLOTS:
        assert (out / name).stat().st_size > 10_000, name
    if path.stem == "straight_push":
        assert (out / "train.gif").stat().st_size > 10_000
    assert (out / "results.npz").is_file() and (out / "run.log").is_file()
    assert (out / RUN_MARKER).is_file()
    assert (out / "path.json").is_file() == (summary["mission"] == "plan")
    assert not list(out.glob(".*.part"))
