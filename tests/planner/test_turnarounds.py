"""Turning round (issue 34 item 2): round an island and back out of the same door, a turn in a
hall, a K-turn in a T junction, at the defaults; the loop round that leads the search when the
goal is behind the train, and the K-turn connection where there is no loop."""

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from pushtrain.mission import runner
from pushtrain.mission.scenario import parse_scenario
from pushtrain.planner.config import PlannerConfig
from pushtrain.planner.heuristic import Heuristic
from pushtrain.planner.passage import needed_half_width, swept_band
from pushtrain.planner.route import loop_route

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _example(name: str, n: int):
    data = tomllib.loads((EXAMPLES / f"{name}.toml").read_text())
    data["train"]["n"] = n
    return parse_scenario(data, name)


def _pose(p) -> tuple:
    return (p.x, p.y, math.radians(p.theta_deg))


def _loop(name: str, n: int):
    """The pushing-only way round of the example's mission (None if there is none), the ring
    the turning train sweeps and the map's distance field."""
    sc = _example(name, n)
    train = runner.train_of(sc)
    field = runner.world_of(sc).distance_field()
    radius = PlannerConfig().radius_for(train)
    margins = PlannerConfig().margins(train)
    passage = needed_half_width(train, margins[-1])
    ring = swept_band(train, radius, margins)
    heuristic = Heuristic(field, _pose(sc.goal), radius, passage, build_car=False)
    radii = (ring.r_in + passage, ring.r_out - passage)
    return heuristic.build_loop(_pose(sc.start), radii), ring, field


def test_the_loop_goes_round_the_island_because_the_train_cannot_turn_in_front_of_it():
    """In front of the island the aisle is 2 m wide; a forward U-turn of the train sweeps a
    ring of outer radius r_out (about 1.4 m: 2.8 m across): the way round leaves the room's
    front aisle, passes behind the island (x > 10) and comes back out of the door."""
    points, ring, field = _loop("island_loop", 4)
    assert 2.0 * ring.r_out > 2.0  # the aisle in front of the island (2 < x < 4)
    assert points is not None
    assert points[:, 0].max() > 10.0  # behind the island (4 < x < 10)
    assert np.all(field.at(points[:, 0], points[:, 1]) > 0.0)
    assert math.hypot(*(points[-1] - (-0.6, 0.0))) < 0.01


def test_there_is_no_loop_in_a_t_junction_too_narrow_to_turn_in():
    """The T junction's hall is 1.5 m wide, less than the ring a forward U-turn sweeps
    (2 r_out): no pushing-only way turns the train round; the K-turn's pulls must."""
    points, ring, _ = _loop("t_junction_kturn", 3)
    assert 2.0 * ring.r_out > 1.5
    assert points is None


def test_the_k_turn_connection_pulls_back_across_the_junction_and_pushes_round_onto_the_goal(
        monkeypatch):
    """From the train pushed into the T junction's left branch (its chain bent: a straight
    push as long as the train first), the K-turn connection (of the search that planned the
    mission) pushes on, pulls straight back past the corridor and pushes round the corner
    onto the goal; the mission needs it (the route leaves against the start)."""
    from pushtrain.core.segment import PULL, PUSH
    from pushtrain.planner.connect import sample_reference
    from pushtrain.planner.goal_connections import GoalConnections

    made = []
    init = GoalConnections.__init__

    def record(self, *args, **kwargs):
        init(self, *args, **kwargs)
        made.append(self)

    monkeypatch.setattr(GoalConnections, "__init__", record)
    sc = _example("t_junction_kturn", 4)
    runner.plan_path(sc)
    connections, goal = made[-1], _pose(sc.goal)
    assert connections.turning_round()
    in_branch = (-1.5, 0.9, 0.0)  # pushed west (-x) into the left branch
    kturns = list(connections.kturns(in_branch, bent=True))
    assert kturns
    for _, segments in kturns:
        assert [g.direction for g in segments[:2]] == [PUSH, PULL]
        assert all(g.direction == PUSH for g in segments[2:])
        end = sample_reference(in_branch, segments, 0.05)[-1]
        assert math.hypot(end[0] - goal[0], end[1] - goal[1]) < 1e-6
        pulled = sample_reference(in_branch, segments[:2], 0.05)[-1]
        assert pulled[0] > 0.75  # past the corridor (|x| < 0.75)


def test_a_point_of_a_loop_projects_onto_the_stretch_travelled_its_way():
    """A loop passes the door twice, in and out: the start (pushed in, +x) projects onto the
    way in, the same place pushed out (-x) onto the way out, near the loop's end."""
    points, _, field = _loop("island_loop", 3)
    route = loop_route(points, field, 0.35)
    along_in, off_in = route.project(1.0, 0.0, 0.0)
    along_out, off_out = route.project(1.0, 0.0, math.pi)
    assert along_in < 1.0 and along_out > route.length - 3.0
    assert off_in < 0.3 and off_out < 0.3


CASES = ([("island_loop", n) for n in (1, 2, 3, 4, 5)] + [("hall_reversal_5", 5)]
         + [("t_junction_kturn", n) for n in (4, 5)])


@pytest.mark.parametrize("name,n", CASES)
def test_the_turnaround_plans_at_the_defaults(name, n):
    """The turnaround plans with the scenario's defaults (counted budget: deterministic), and
    the planner's closed-loop train ends at the goal; the island loop with 4 or 5 trailers
    goes round the island (no room in front of it, see above); the K-turn is the driver's
    (push into a branch, pull straight back across the junction, push round into the
    corridor: two cusps), found by the K-turn connection in a few hundred expansions (1400
    without it with 4 trailers)."""
    sc = _example(name, n)
    path = runner.plan_path(sc)
    goal = _pose(sc.goal)
    assert math.hypot(path.goal[0] - goal[0], path.goal[1] - goal[1]) < 0.05
    assert abs(math.remainder(path.goal[2] - goal[2], 2 * math.pi)) < math.radians(3)
    assert not path.info["time_capped"]
    if name == "island_loop" and n >= 4:
        assert path.poses[:, 0].max() > 10.0 and path.n_cusps == 0
    if name == "t_junction_kturn":
        assert path.n_cusps == 2 and path.info["expansions"] <= 600


def test_the_office_t_junction_with_five_trailers_pulls_back_onto_the_goal():
    """Willow Garage's office (public map): five trailers up the middle corridor into the
    north hall, to stop at its T junction pushed east. A driver pushes up the hall's diagonal
    until the train is straight and pulls it back round onto the goal; the goal is so near
    the diagonal's end that a 1 m settling pull after the arc would start where the push
    before it meets the wall, so the pull-back settles in 0.5 m. Plans at the defaults with
    one cusp in a few dozen expansions (the 1 m pull-backs alone: the default budget spent,
    and a 240 s search found nothing)."""
    office = EXAMPLES / "maps" / "public" / "willow_garage.yaml"
    sc = parse_scenario({"mission": {"kind": "plan"}, "train": {"n": 5},
                         "map": {"grid": str(office)},
                         "start": {"x": 9.4, "y": 21.0, "theta_deg": -85.0},
                         "goal": {"x": 15.0, "y": 46.8, "theta_deg": 180.0}}, "office_t5")
    path = runner.plan_path(sc)
    goal = _pose(sc.goal)
    assert math.hypot(path.goal[0] - goal[0], path.goal[1] - goal[1]) < 0.05
    assert path.n_cusps == 1 and path.info["expansions"] <= 200
    last = path.segments[-1]
    assert last.direction < 0 and last.kind == "line" and last.length == pytest.approx(0.5)
