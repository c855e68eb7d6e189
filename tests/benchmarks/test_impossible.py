"""The facility benchmark's impossible missions (benchmarks/facility/impossible.toml): each proof
holds on the map's occupancy grid by the test's own distance transform, and the planner at its
defaults says "impossible here" before any search, naming the widest way's narrowest opening
within one map cell of it (issue 34 item 3)."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from pushtrain.errors import PlanningError

BENCH = Path(__file__).resolve().parents[2] / "benchmarks"
sys.path.insert(0, str(BENCH))

import bench_facility  # noqa: E402

PROOFS = bench_facility.impossible_reasons()
MISSIONS = {m["key"]: m for m in bench_facility.load_missions()}
EIGHT = np.ones((3, 3), dtype=bool)


def test_the_benchmark_holds_impossible_missions_on_public_maps():
    assert len(PROOFS) >= 6
    assert {MISSIONS[k]["map"] for k in PROOFS} >= {"office"}


def _grid_and_cells(mission):
    from pushtrain.facility.loading import map_world

    grid = map_world(grid=mission["grid"]).occupancy
    h = grid.resolution
    # the test's own transform: metres from every cell's centre to the nearest blocked
    # cell's centre, outside the grid blocked
    edt = ndimage.distance_transform_edt(np.pad(~grid.blocked, 1))[1:-1, 1:-1] * h

    def cell(p):
        return round((p[1] - grid.y0) / h), round((p[0] - grid.x0) / h)

    return grid, edt, cell(mission["start"]), cell(mission["goal"])


def _joined(edt, a, b, keep) -> bool:
    labels, _ = ndimage.label(keep, structure=EIGHT)
    return bool(labels[a] > 0 and labels[a] == labels[b])


@pytest.mark.parametrize("key", sorted(PROOFS))
def test_the_proof_holds_on_the_maps_grid(key):
    """No 8-connected way of cells keeping the disc's radius less 0.207 of a cell (every cell
    the last trailer's axle midpoint can cross, see prove_impossible.py) joins start and goal;
    the recorded width is the widest way's: cells at its level join them, none above."""
    proof, mission = PROOFS[key], MISSIONS[key]
    grid, edt, a, b = _grid_and_cells(mission)
    h = grid.resolution
    assert proof["cell"] == h and proof["needed"] == pytest.approx(0.70)  # 0.6 m + 2 x 0.05
    level = 0.5 * proof["needed"] - h / math.sqrt(2.0) + 0.5 * h
    assert edt[a] >= level and edt[b] >= level  # the ends themselves have room
    assert not _joined(edt, a, b, edt >= level)
    m = 0.5 * (proof["width"] + 0.5 * h)  # the width is written to the millimetre
    assert _joined(edt, a, b, edt >= m - 1e-3)
    assert not _joined(edt, a, b, edt > m + 1e-3)
    x, y = proof["at"]  # the place named is a cell of that level
    assert edt[round((y - grid.y0) / h), round((x - grid.x0) / h)] == pytest.approx(m, abs=1e-3)


def _explode(*_args, **_kwargs):
    raise AssertionError("the search (or its heuristic) ran for an impossible mission")


@pytest.mark.parametrize("key", sorted(PROOFS))
def test_the_planner_says_impossible_at_once_with_the_true_width(key, monkeypatch):
    """At the scenario's defaults: "impossible here", before the heuristic's grid search or the
    search starts (both would raise), naming a width within one map cell of the test's own
    maximin over the grid's transform and never a narrower passage than that less a cell."""
    import pushtrain.planner.whole_train as whole_train
    from pushtrain.mission import runner

    mission = MISSIONS[key]
    grid, edt, a, b = _grid_and_cells(mission)
    h = grid.resolution
    values = np.unique(edt[edt > 0])
    m = max(v for v in values if _joined(edt, a, b, edt >= v))  # the test's own maximin
    opening = 2.0 * m - 0.5 * h  # 2m - h (centred) to 2m wall to wall
    monkeypatch.setattr(whole_train, "Heuristic", _explode)
    monkeypatch.setattr(whole_train, "Search", _explode)
    with pytest.raises(PlanningError) as info:
        runner.plan_path(bench_facility.scenario_of(mission, None))
    err = info.value
    assert err.reason == "unreachable" and err.details["impossible"], str(err)
    assert "] impossible here: " in str(err), str(err)
    named = err.details["bottleneck"]
    assert named["width"] == pytest.approx(opening, abs=h), (named, opening)
    assert named["needed"] == pytest.approx(0.70)
    assert math.dist((named["x"], named["y"]), PROOFS[key]["at"]) < 1.0
    assert f"narrows to {named['width']:.2f} m" in str(err)
    assert bench_facility.judge_impossible(
        {"status": "no_plan", "impossible": True, "bottleneck": named}, PROOFS[key]) == "true"
