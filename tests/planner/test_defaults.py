"""Defaults that plan (issue 34): the default budget, the car heuristic's pull rule, and a
start a few centimetres off a wall."""

import math
import tomllib
from pathlib import Path

import pytest

from pushtrain.errors import PlanningError
from pushtrain.facility import example_layouts
from pushtrain.facility.free_space import World
from pushtrain.mission import runner
from pushtrain.mission.scenario import parse_scenario
from pushtrain.planner import whole_train
from pushtrain.planner.budget import (
    DEFAULT_SEARCH_SECONDS,
    DEFAULT_WALL_CAP,
    STEPS_PER_SECOND,
    default_steps,
)
from pushtrain.planner.config import PlannerConfig
from pushtrain.planner.heuristic import Heuristic
from pushtrain.planner.planner import plan
from pushtrain.planner.train import Train

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _example(name: str, n: int | None = None, **planner):
    data = tomllib.loads((EXAMPLES / f"{name}.toml").read_text())
    if n is not None:
        data["train"]["n"] = n
    if planner:
        data.setdefault("planner", {}).update(planner)
    return parse_scenario(data, name)


def test_the_default_budget_is_counted_work_of_about_twenty_seconds_whatever_n():
    """No time_budget: the lattice search gets default_steps(n) (counted, no clock); fewer
    steps for longer trains, whose steps cost more; an explicit budget keeps its meaning."""
    config = PlannerConfig()
    assert config.time_budget is None
    assert config.budget_steps(3) == default_steps(3) > 10 * STEPS_PER_SECOND
    assert default_steps(1) > default_steps(3) > default_steps(10) > 10 * STEPS_PER_SECOND
    assert config.budget_seconds() == DEFAULT_SEARCH_SECONDS
    assert PlannerConfig(time_budget=2.0).budget_steps(10) == 2 * STEPS_PER_SECOND
    assert PlannerConfig(planner="rrtconnect").budget_checks() == 1000  # OMPL: 1 s as before
    # the clock's safety net keeps a default run within a minute; an explicit budget keeps
    # its 10 x budget + 10 s
    assert config.wall_cap() == DEFAULT_WALL_CAP <= 50.0
    assert PlannerConfig(time_budget=2.0).wall_cap() == 30.0


def test_the_default_plans_the_k_turn_that_the_old_one_second_did_not():
    """Five trailers K-turned in a T junction (examples/t_junction_kturn.toml): the old
    default of 1 s (150 000 steps) runs out; the scenario's defaults plan it. (The hall
    reversal of five trailers, once this test's case, now plans within the old second: the
    search is led round the hall by its loop, see tests/planner/test_turnarounds.py.)"""
    with pytest.raises(PlanningError) as info:
        runner.plan_path(_example("t_junction_kturn", n=5, time_budget=1.0))
    assert info.value.reason == "budget_exhausted"
    path = runner.plan_path(_example("t_junction_kturn", n=5))
    assert path.info["budget_steps"] == default_steps(5)
    assert 150_000 < path.info["steps"] < default_steps(5)
    assert not path.info["time_capped"]
    goal = (0.0, -2.0, 0.5 * math.pi)
    assert path.goal[0] == pytest.approx(goal[0], abs=0.05)
    assert path.goal[1] == pytest.approx(goal[1], abs=0.05)
    assert abs(math.remainder(path.goal[2] - goal[2], 2 * math.pi)) < math.radians(3)


def test_the_car_pulls_only_after_straightening_and_where_the_straight_train_fits():
    """The T junction's wrong-way pose: a car that may pull anywhere turns round for less than
    one that must first push the chain straight (3 m) and may pull only where the straight
    train fits; a train longer than every branch cannot turn round at all (no pull anywhere
    that brings it round), which the car's cost says."""
    case = example_layouts.t_junction()
    field = World.from_dict(case["world"]).distance_field()
    wrong_way = (1.0, 1.0, math.pi)

    def car(**options):
        return Heuristic(field, case["goal"], 0.97, 0.35, car=options).car(wrong_way)

    free = car()
    rule = car(straighten=3.0, train_length=3.12)
    assert free < math.inf and rule > free + 2.0
    # the branch is 5 m deep and the corridor 2 m wide: a 7.5 m train has no straight spot
    # to pull from that turns it round
    assert car(straighten=3.0, train_length=7.5) > rule + 2.0


def test_a_start_six_centimetres_off_a_wall_moves_off_it(monkeypatch):
    """A trailer 0.06 m from the wall with a 0.05 m clearance passes the exact test but not
    the sampled one (conservative by half its 4 cm spacing): without finer samples no motion
    could leave the start. (Along the wall: a turn away from it swings the trailer's rear
    toward it by more than the centimetre the clearance leaves.)"""
    world = World.from_dict({"free": [[0.0, 0.0], [12.0, 0.0], [12.0, 1.4], [0.0, 1.4]]})
    start = (6.0, 0.3 + 0.06, math.pi)  # pushed toward +x, its right side 6 cm off y = 0
    goal = (10.5, 0.3 + 0.06, math.pi)
    path = plan(world, start, goal, Train.uniform(1), PlannerConfig())
    assert path.info["train_check"]["min_clearance"] >= 0.0  # beyond the 0.05 m clearance
    monkeypatch.setattr(whole_train, "FINE_SPACINGS", ())
    with pytest.raises(PlanningError) as info:
        plan(world, start, goal, Train.uniform(1), PlannerConfig())
    assert info.value.details["expansions"] <= 1
