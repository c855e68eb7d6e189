"""What the commands share (:mod:`pushtrain.cli.common`, :mod:`pushtrain.cli.runs`): the
``--trailers`` override of a scenario, and the path summary's turn sides against the
geometry of the path."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from pushtrain.cli.common import BadInput, load_scenario_with_overrides
from pushtrain.cli.main import cli
from pushtrain.cli.runs import describe_path
from pushtrain.core.segment import PUSH, Segment
from pushtrain.planner.connect import sample_reference
from pushtrain.planner.path import PlannedPath

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _with_lengths(tmp_path, horizon: float | None = None) -> Path:
    text = (EXAMPLES / "straight_push.toml").read_text()
    text = text.replace("[train]\nn = 3\n", "[train]\nn = 3\nfront = [0.5, 0.55, 0.6]\n"
                                            "rear = [0.45, 0.5, 0.55]\n")
    if horizon is not None:
        text += f"horizon = {horizon}\n"
    path = tmp_path / "lengths.toml"
    path.write_text(text)
    return path


def test_trailers_over_a_scenario_listing_the_lengths_runs_with_the_default_lengths(tmp_path):
    path = _with_lengths(tmp_path)
    sc = load_scenario_with_overrides(str(path), trailers=2)
    assert sc.train.n == 2 and sc.train.front is None and sc.train.rear is None
    assert load_scenario_with_overrides(str(path)).train.rear == [0.45, 0.5, 0.55]


def test_trailers_over_the_lengths_runs_from_the_command_line(tmp_path):
    out = tmp_path / "out"
    done = CliRunner().invoke(cli, ["plan-and-run", str(_with_lengths(tmp_path, horizon=1.0)),
                                    "--trailers", "2", "--no-plots", "--out", str(out)])
    assert done.exit_code == 1, done.output  # ran (too short a horizon to arrive): not refused
    assert (out / "results.npz").is_file()


def test_trailers_over_a_list_of_masses_is_refused_naming_it(tmp_path):
    text = (EXAMPLES / "straight_push.toml").read_text().replace(
        "[train]\nn = 3\n", "[train]\nn = 3\nmass = [40.0, 50.0, 60.0]\n")
    path = tmp_path / "masses.toml"
    path.write_text(text)
    with pytest.raises(BadInput, match=r"train\.mass.*a single value when --trailers"):
        load_scenario_with_overrides(str(path), trailers=2)


def _turns_left(start, seg) -> bool:
    """Whether the travel along ``seg`` from ``start`` turns counter-clockwise (to the left as
    seen travelling), from sampled positions."""
    poses = sample_reference(start, [seg], seg.length / 20)
    d = np.diff(poses[:, :2], axis=0)
    cross = d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0]
    assert np.all(np.sign(cross) == np.sign(cross[0]))
    return bool(cross[0] > 0)


@pytest.mark.parametrize("direction", [PUSH, -PUSH])
def test_the_path_summary_names_the_side_each_arc_turns_to(direction):
    quarter = math.pi / 2
    segments = (Segment("arc", quarter, 1.0, direction), Segment("line", 1.0, 0.0, direction),
                Segment("arc", quarter * 0.5, -2.0, direction))
    path = PlannedPath(np.array([0.0, 0.0, 0.3]), segments, 0.5)
    lines = describe_path(path).splitlines()[1:]
    pose = (0.0, 0.0, 0.3)
    for seg, line in zip(segments, lines, strict=True):
        if seg.kind == "arc":
            side = "left" if _turns_left(pose, seg) else "right"
            assert line.split()[4] == side, line
            assert f"r={1 / abs(seg.curvature):.2f} m" in line
        pose = tuple(sample_reference(pose, [seg], seg.length + 1.0)[-1])
