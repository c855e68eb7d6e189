"""The whole-train planner (``planner = "lattice"``): corner paths, plans of the facility
manoeuvres, determinism under load, budgets and failure diagnostics."""

import json
import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from pushtrain.core.reference import Reference
from pushtrain.core.segment import PULL, PUSH
from pushtrain.errors import PlanningError
from pushtrain.facility import example_layouts
from pushtrain.facility.free_space import World
from pushtrain.planner.config import PlannerConfig
from pushtrain.planner.connect import corner_segments
from pushtrain.planner.planner import plan
from pushtrain.planner.smooth import merge, total_turning
from pushtrain.planner.train import Train

TRAIN = Train.uniform(3)


def _end(pose, segments):
    ref = Reference.from_segments(pose, segments, speed=1.0, cusp_dwell=0.0)
    x, y, th, _, _ = ref.sample([ref.t_end])
    return x[0], y[0], th[0]


@pytest.mark.parametrize("direction", [PUSH, PULL])
@pytest.mark.parametrize("turn_deg", [30.0, 90.0, -90.0, 135.0])
def test_a_corner_path_lands_on_its_goal(direction, turn_deg):
    pose = (0.0, 0.0, math.pi if direction == PUSH else 0.0)  # both travel toward +x
    turn = math.radians(turn_deg)
    # the goal: 3 m ahead, then 2.5 m along the turned direction
    gx, gy = 3.0 + 2.5 * math.cos(turn), 2.5 * math.sin(turn)
    goal = (gx, gy, pose[2] + turn)
    for radius in (None, 1.0):
        path = corner_segments(pose, goal, direction, radius, max_radius=2.0)
        kinds = [g.kind for g in path]
        assert kinds.count("arc") == 1 and kinds in (["line", "arc", "line"], ["line", "arc"])
        assert all(g.direction == direction for g in path)
        x, y, th = _end(pose, path)
        assert (x, y) == pytest.approx((gx, gy), abs=1e-9)
        assert math.remainder(th - goal[2], 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
        arc = path[kinds.index("arc")]
        assert abs(arc.curvature) * arc.length == pytest.approx(abs(turn))
        if radius is None:  # the widest arc that fits, up to max_radius
            expected = min(2.0, 2.5 / math.tan(0.5 * abs(turn)))
            assert 1.0 / abs(arc.curvature) == pytest.approx(expected)


def test_corner_paths_that_do_not_exist():
    # the goal's line of travel meets the pose's behind it
    assert corner_segments((0.0, 0.0, math.pi), (-3.0, 2.0, math.pi / 2), PUSH) is None
    # an arc too wide for the corner
    assert corner_segments((0.0, 0.0, math.pi), (1.0, 1.0, -math.pi / 2), PUSH, 2.0) is None
    # collinear: one line, or nothing if the goal lies behind
    line = corner_segments((0.0, 0.0, math.pi), (2.0, 0.0, math.pi), PUSH)
    assert [(g.kind, g.length) for g in line] == [("line", pytest.approx(2.0))]
    assert corner_segments((0.0, 0.0, math.pi), (-2.0, 0.0, math.pi), PUSH) is None


def test_merge_keeps_the_reference_and_joins_equal_pieces():
    case = example_layouts.docking_bay()
    path = corner_segments(case["start"], case["goal"], PUSH, 1.0)
    pieces = []
    for g in path:
        pieces += [type(g)(g.kind, g.length / 4, g.curvature, g.direction)] * 4
    merged = merge(pieces)
    assert len(merged) == len(path)
    assert _end(case["start"], merged) == pytest.approx(_end(case["start"], pieces), abs=1e-9)
    assert total_turning(merged) == pytest.approx(math.pi / 2)


def _plan(name, **settings):
    case = example_layouts.CASES[name]()
    n = {"narrow_l": 5, "corner_10": 10}.get(name, 3)
    train = Train.uniform(n)
    world = World.from_dict(case["world"])
    config = PlannerConfig(time_budget=600.0, **settings)
    return case, world, train, plan(world, case["start"], case["goal"], train, config)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["docking", "narrow_l", "parallel", "t_junction", "bay",
                                  "l_2.0"])
def test_the_manoeuvres_plan_and_the_whole_train_keeps_its_clearance(name):
    case, world, train, path = _plan(name)
    check = path.info["train_check"]
    # the closed loop reaches the goal within the tolerance (5 cm, 5 deg by default)
    assert check["goal_error"][0] <= 0.05 and check["goal_error"][1] <= math.radians(5.0)
    # every body keeps its clearance (measured exactly, shapely) and no joint passes the limit
    assert check["wall_clearance"] >= 0.05 - 1e-9
    assert max(check["max_abs_phi"]) <= train.phi_max - math.radians(5.0) + 1e-9
    assert np.allclose(path.goal[:2], case["goal"][:2], atol=1e-6)
    if name == "t_junction":
        # a three-point turn: pushed into the branch, pulled out the other way
        assert path.n_cusps >= 1 and {g.direction for g in path.segments} == {PUSH, PULL}
        # every pull starts where the simulated chain is straight within the pull rule
        phi = path.joint_angles()
        for k in path.cusps:
            if path.segments[path.interval_segment[k]].direction == PULL:
                assert np.abs(phi[k]).max() <= math.radians(15.0) + 0.02
    if name == "docking":
        assert path.n_cusps == 0


def test_a_goal_closer_to_the_wall_than_the_clearance_is_refused_with_numbers():
    case = example_layouts.docking_bay()
    world = World.from_dict(case["world"])
    with pytest.raises(PlanningError) as info:
        plan(world, case["start"], case["goal"], TRAIN, PlannerConfig(clearance=0.2))
    err = info.value
    assert err.reason == "goal_in_collision"
    assert "keeps only 0.150 m" in str(err) and "asks 0.200 m" in str(err)
    assert err.details["gap"] == pytest.approx(0.15, abs=1e-6)
    assert err.details["constraint"] == "goal footprint vs clearance"


def test_the_start_in_a_wall_names_the_body():
    case = example_layouts.l_corridor(2.0)
    world = World.from_dict(case["world"])
    with pytest.raises(PlanningError) as info:
        plan(world, (2.0, 1.0, math.pi), case["goal"], TRAIN)
    assert info.value.reason == "start_in_collision"
    assert info.value.details["body"] == 0 and "robot" in str(info.value)


def test_separated_rooms_are_unreachable_at_once():
    case = example_layouts.two_rooms(0.5)
    world = World.from_dict(case["world"])
    with pytest.raises(PlanningError) as info:
        plan(world, case["start"], case["goal"], TRAIN)
    err = info.value
    assert err.reason == "unreachable" and "impossible here" in str(err)
    # the slit (x from 5 to 6, 0.5 m wide) is named against the 0.6 m trailer's 0.7 m
    assert "needs passages 0.70 m wide" in str(err) and "narrows to 0.50 m" in str(err)
    bottleneck = err.details["bottleneck"]
    assert 5.0 - 0.05 <= bottleneck["x"] <= 6.0 + 0.05
    assert bottleneck["y"] == pytest.approx(2.5, abs=0.05)
    assert bottleneck["width"] == pytest.approx(0.5, abs=0.03)


def test_separate_parts_of_the_map_are_named_as_such():
    case = example_layouts.two_rooms(0.0)
    world = World.from_dict(case["world"])
    with pytest.raises(PlanningError) as info:
        plan(world, case["start"], case["goal"], TRAIN)
    assert info.value.reason == "unreachable"
    assert "separate parts of the map" in str(info.value)


def test_a_joint_limit_that_forbids_the_corner_says_so(monkeypatch):
    """With phi_max = 25 deg the train cannot turn round the L's corner: the search runs out of
    states or budget, and the message counts the motions the joint limit stopped."""
    import pushtrain.planner.budget as budget

    monkeypatch.setattr(budget, "STEPS_PER_SECOND", 20_000)
    case = example_layouts.l_corridor(2.0)
    world = World.from_dict(case["world"])
    train = Train.uniform(3, phi_max=math.radians(25.0))
    config = PlannerConfig(time_budget=3.0, joint_margin=math.radians(2.0))
    with pytest.raises(PlanningError) as info:
        plan(world, case["start"], case["goal"], train, config)
    err = info.value
    assert err.reason in ("budget_exhausted", "unreachable")
    assert err.details["failures"].get("joint_limit", 0) > 0
    assert "bent a joint beyond 23.0 deg" in str(err)
    # the budget is counted in simulated steps and never exceeded
    assert err.details["steps"] <= config.budget_steps()
    # what the picture needs
    assert err.details["tree"] and err.details["closest"]["segments"] is not None
    assert err.details["margins"] == [0.05] * 4


def _plan_in_subprocess(name: str) -> subprocess.Popen:
    code = textwrap.dedent(f"""
        import json
        from pushtrain.facility import example_layouts
        from pushtrain.planner.config import PlannerConfig
        from pushtrain.planner.planner import plan
        from pushtrain.facility.free_space import World
        from pushtrain.planner.train import Train
        case = example_layouts.CASES[{name!r}]()
        path = plan(World.from_dict(case["world"]), case["start"], case["goal"],
                    Train.uniform(3), PlannerConfig(time_budget=300.0))
        print(json.dumps({{"segments": path.to_dict()["segments"],
                           "capped": path.info["time_capped"], "steps": path.info["steps"]}}))
    """)
    return subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)


@pytest.mark.slow
def test_the_same_plan_under_load():
    """Two plans at once (each slowing the other down) give the same path and the same work:
    the search's work decides, never the clock."""
    procs = [_plan_in_subprocess("parallel") for _ in range(2)]
    outs = [json.loads(p.communicate(timeout=900)[0]) for p in procs]
    assert all(p.returncode == 0 for p in procs)
    assert not outs[0]["capped"] and not outs[1]["capped"]
    assert outs[0] == outs[1]


def test_an_exact_test_that_would_end_past_the_safety_cap_is_not_started(monkeypatch):
    """The exact test cannot be interrupted: with its cost estimated past the wall-clock safety
    cap (10 x time_budget + 10 s) the planner stops, says the clock cut it short, and names the
    cap; with a small estimate the same problem plans."""
    from pushtrain.planner import whole_train

    case = example_layouts.l_corridor(2.0)
    world = World.from_dict(case["world"])
    config = PlannerConfig(time_budget=2.0)
    monkeypatch.setattr(whole_train, "_EXACT_RATE", [1.0])  # 1 s per state and body
    with pytest.raises(PlanningError) as info:
        plan(world, case["start"], case["goal"], TRAIN, config)
    err = info.value
    assert err.reason == "budget_exhausted" and err.details["time_capped"]
    assert err.details["constraint"] == "budget" and "safety cap of 30 s" in str(err)
    monkeypatch.setattr(whole_train, "_EXACT_RATE", [1e-9])
    path = plan(world, case["start"], case["goal"], TRAIN, config)
    assert not path.info["time_capped"]
    # the rate is measured again by every exact test
    assert whole_train._EXACT_RATE[0] > 1e-9


def _corridor_into_a_hall(corridor: float = 2.0, hall: float = 2.0) -> dict:
    """A corridor ``corridor`` wide going up +y into a hall ``hall`` wide along x (a T
    junction, as the office floor's west corridor meets its north hall). The train comes up
    the corridor pushed north and must stop at the junction pushed east along the hall, the
    robot west of the last trailer: the route comes in across the goal."""
    c, h = float(corridor), float(hall)
    free = [[-0.5 * c, -12.0], [0.5 * c, -12.0], [0.5 * c, 0.0], [9.0, 0.0], [9.0, h],
            [-9.0, h], [-9.0, 0.0], [-0.5 * c, 0.0]]
    return {"world": {"free": free}, "start": (0.0, -8.0, -0.5 * math.pi),
            "goal": (0.0, 0.5 * h, math.pi)}


def test_the_pull_back_of_a_turn_round_lands_on_the_goal():
    """The pull-back connections' pulls, computed backward from the goal, end on it."""
    from pushtrain.core.segment import Segment
    from pushtrain.planner.connect import sample_reference
    from pushtrain.planner.goal_connections import _reversed

    goal = (15.0, 46.8, math.pi)
    pull = [Segment("line", 3.62, 0.0, PULL), Segment("arc", 0.6, -1.03, PULL),
            Segment("line", 1.0, 0.0, PULL)]
    start = sample_reference(goal, _reversed(pull), 0.05)[-1]
    assert start[2] == pytest.approx(math.pi + 0.6 * 1.03)
    end = sample_reference(tuple(start), pull, 0.05)[-1]
    assert end == pytest.approx(goal, abs=1e-9)


def test_a_train_coming_up_a_corridor_turns_round_at_the_t_junction():
    """Up a corridor into a hall, to stop at the junction pushed along the hall: the train
    is pushed round the corner into the hall's far branch until it is straight, then pulled
    back onto the junction (one cusp), as a tugger driver does. Without the pull-back
    connections the search used the whole 10 s budget here (716 expansions) and found no
    plan; with them the first expansion connects."""
    case = _corridor_into_a_hall()
    world = World.from_dict(case["world"])
    config = PlannerConfig(time_budget=10.0)
    path = plan(world, case["start"], case["goal"], TRAIN, config)
    assert path.info["expansions"] <= 20 and path.info["steps"] < config.budget_steps() // 10
    assert path.n_cusps == 1
    directions = [g.direction for g in path.segments]
    assert directions == sorted(directions, reverse=True)  # pushes, then pulls
    # pushed into the east branch beyond the whole train's length, then pulled back west
    train_length = float(np.sum(TRAIN.geometry.front) + np.sum(TRAIN.geometry.rear))
    assert path.poses[:, 0].max() >= case["goal"][0] + train_length
    # the pull starts where the simulated chain is straight (the pull rule)
    phi = path.joint_angles()
    (cusp,) = path.cusps
    assert np.abs(phi[cusp]).max() <= math.radians(15.0) + 0.02
    check = path.info["train_check"]
    assert check["goal_error"][0] <= 0.05 and check["goal_error"][1] <= math.radians(5.0)
    assert check["wall_clearance"] >= 0.05 - 1e-9
