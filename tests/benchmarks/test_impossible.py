"""The facility benchmark's impossible missions (benchmarks/facility/impossible.toml): each proof
holds on the scenario's World (the traced free space the co-simulation checks against) by the
test's own shapely erosion, its width is tight (a disc 2 cm narrower joins start and goal, one
2 mm wider does not), and the planner at its defaults says "impossible here" before any search,
naming that width within the benchmark's tolerance (issue 34 items 3-4)."""

import functools
import math
import sys
from pathlib import Path

import pytest
from shapely.geometry import Point

from pushtrain.errors import PlanningError

BENCH = Path(__file__).resolve().parents[2] / "benchmarks"
sys.path.insert(0, str(BENCH))

import bench_facility  # noqa: E402

PROOFS = bench_facility.impossible_reasons()
MISSIONS = {m["key"]: m for m in bench_facility.load_missions()}


def test_the_benchmark_holds_impossible_missions_on_public_maps():
    assert len(PROOFS) >= 6
    assert {MISSIONS[k]["map"] for k in PROOFS} >= {"office"}


@functools.cache
def _free(grid: str):
    from pushtrain.facility.loading import map_world

    return map_world(grid=grid).free


@functools.cache
def _eroded(grid: str, radius: float):
    """The map's free space eroded by ``radius`` [m] (shapely, 64 chords a quarter circle)."""
    return _free(grid).buffer(-radius, quad_segs=64)


def _joined(grid: str, start: tuple, goal: tuple, radius: float) -> bool:
    """Whether the map's free space eroded by ``radius`` [m] holds start and goal in one
    part."""
    eroded = _eroded(grid, radius)
    s, g = Point(start), Point(goal)
    for part in getattr(eroded, "geoms", (eroded,)):
        if part.covers(s):
            return part.covers(g)
    return False


def _ends(mission):
    return tuple(mission["start"][:2]), tuple(mission["goal"][:2])


def _needed(mission) -> float:
    """Twice the planner's own radius for the scenario's last trailer at its default
    clearance (the proof must ask what the planner asks)."""
    from pushtrain.mission import runner
    from pushtrain.planner.config import PlannerConfig
    from pushtrain.planner.passage import needed_half_width

    train = runner.train_of(bench_facility.scenario_of(mission, None))
    return 2.0 * needed_half_width(train, PlannerConfig().margins(train)[-1])


@pytest.mark.parametrize("key", sorted(PROOFS))
def test_the_proof_holds_on_the_scenarios_world(key):
    """Eroded by half the width the planner says the train needs, the free space leaves start
    and goal in separate parts, both ends keeping room; the recorded width is the widest
    disc's: 2 cm less joins them, 2 mm more does not."""
    proof, mission = PROOFS[key], MISSIONS[key]
    needed = _needed(mission)
    assert proof["needed"] == pytest.approx(needed, abs=5e-4)
    grid, (start, goal) = mission["grid"], _ends(mission)
    eroded = _eroded(grid, 0.5 * needed)
    assert eroded.covers(Point(start)) and eroded.covers(Point(goal))  # the ends have room
    assert not _joined(grid, start, goal, 0.5 * needed)
    assert proof["width"] < needed
    assert _joined(grid, start, goal, 0.5 * (proof["width"] - 0.02))
    assert not _joined(grid, start, goal, 0.5 * (proof["width"] + 0.002))


def _explode(*_args, **_kwargs):
    raise AssertionError("the search (or its heuristic) ran for an impossible mission")


@pytest.mark.parametrize("key", sorted(PROOFS))
def test_the_planner_says_impossible_at_once_with_the_true_width(key, monkeypatch):
    """At the scenario's defaults: "impossible here", before the heuristic's grid search or the
    search starts (both would raise), naming the proof's width within the benchmark's
    tolerance (5 cm: half the office map's cell) near the proof's place, and never a width
    below the proof's by more than 3 mm (no message may name a passage narrower than the
    map's)."""
    import pushtrain.planner.whole_train as whole_train
    from pushtrain.mission import runner

    mission, proof = MISSIONS[key], PROOFS[key]
    monkeypatch.setattr(whole_train, "Heuristic", _explode)
    monkeypatch.setattr(whole_train, "Search", _explode)
    with pytest.raises(PlanningError) as info:
        runner.plan_path(bench_facility.scenario_of(mission, None))
    err = info.value
    assert err.reason == "unreachable" and err.details["impossible"], str(err)
    assert "] impossible here: " in str(err), str(err)
    named = err.details["bottleneck"]
    assert bench_facility.WIDTH_TOLERANCE <= 0.05
    assert named["width"] == pytest.approx(proof["width"], abs=0.05), (named, proof)
    assert named["width"] >= proof["width"] - 0.003, (named, proof)
    assert named["needed"] == pytest.approx(proof["needed"])
    assert math.dist((named["x"], named["y"]), proof["at"]) < 0.5
    assert f"narrows to {named['width']:.2f} m" in str(err)
    assert bench_facility.judge_impossible(
        {"status": "no_plan", "impossible": True, "bottleneck": named}, proof) == "true"
