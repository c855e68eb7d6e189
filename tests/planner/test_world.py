"""World construction, footprints and the validity orientation."""

import math

import pytest
from shapely.geometry import Polygon

from pushtrain.errors import PlanningInputError
from pushtrain.facility import example_layouts
from pushtrain.facility.free_space import World
from pushtrain.planner.diagnostic import save_diagnostic
from pushtrain.planner.train import BodyFootprint, Train


def test_from_dict_outline_and_obstacles():
    w = World.from_dict({"free": [[0, 0], [10, 0], [10, 4], [0, 4]],
                         "obstacles": [[[4, 1], [6, 1], [6, 3], [4, 3]]],
                         "walls": [[[0, 3.5], [10, 3.5], [10, 4], [0, 4]]]})
    assert w.free_area == pytest.approx(40 - 4 - 5)
    assert w.contains_point(1, 1) and not w.contains_point(5, 2) and not w.contains_point(1, 3.7)
    again = World.from_dict(w.to_dict())
    assert again.free_area == pytest.approx(w.free_area)


def test_from_dict_bounds_and_errors():
    assert World.from_dict({"bounds": [0, 0, 3, 2]}).free_area == pytest.approx(6.0)
    with pytest.raises(PlanningInputError, match="unknown keys"):
        World.from_dict({"free": [[0, 0], [1, 0], [1, 1]], "roads": []})
    with pytest.raises(PlanningInputError, match="world.free"):
        World.from_dict({"free": [[0, 0], [1, 0]]})
    with pytest.raises(PlanningInputError, match="bounds"):
        World.from_dict({"bounds": [0, 0, -1, 2]})
    with pytest.raises(PlanningInputError, match="'free'"):
        World.from_dict({})


def test_footprint_corners_follow_heading_and_offset():
    fp = BodyFootprint(length=1.0, width=0.4, offset=0.3)
    c = fp.corners(2.0, 1.0, math.pi / 2)  # heading +y: rectangle centre at (2, 1.3)
    assert c.mean(axis=0) == pytest.approx([2.0, 1.3])
    assert c[:, 1].max() == pytest.approx(1.8) and c[:, 1].min() == pytest.approx(0.8)
    assert c[:, 0].max() == pytest.approx(2.2)
    assert Polygon(c).area == pytest.approx(0.4)
    with pytest.raises(PlanningInputError, match="offset"):
        BodyFootprint(1.0, 0.4, 0.6)


def test_validity_uses_last_trailer_in_chain_orientation():
    """The planner state yaw is theta + pi; an offset footprint must land on the theta side."""
    from pushtrain.planner.ompl_search import Attempt, solve_once

    # a dead-end pocket: free only for x in [0, 3]; the last trailer's rectangle sticks out
    # 0.6 m toward the robot (theta side). At x = 0.5 with theta = 0 it fits; theta = pi not.
    world = World.from_dict({"free": [[0, 0], [3, 0], [3, 2], [0, 2]]})
    trailer = BodyFootprint(length=1.2, width=0.6, offset=0.55)
    train = Train.uniform(1, trailer=trailer)
    cfg_ok = dict(inflation=0.0, offtrack_allowance=0.0)
    from pushtrain.planner.config import PlannerConfig

    cfg = PlannerConfig(planner="rrtconnect", **cfg_ok, time_budget=0.2, check_train=False,
                        straight_pull_ends=False)
    att = Attempt(1.0, 0.0)
    # start pose with theta = 0: rectangle spans x in [0.5 + 0.55 - 0.6, 0.5 + 0.55 + 0.6]
    states, _ = solve_once(
        world, train, (0.5, 1.0, 0.0 + math.pi), (1.5, 1.0, math.pi), cfg, att, 200, 3
    )
    assert states.shape[1] == 3
    from pushtrain.errors import PlanningError

    with pytest.raises(PlanningError):
        # theta = pi puts the rectangle at x in [-0.65, 0.55]: outside the map -> invalid start
        solve_once(
            world, train, (0.5, 1.0, math.pi + math.pi), (1.5, 1.0, math.pi), cfg, att, 200, 3
        )


def test_worlds_are_plain_data_and_diagnostic_png(tmp_path):
    for name, factory in example_layouts.CASES.items():
        case = factory()
        world = World.from_dict(case["world"])
        assert world.free_area > 1.0, name
        assert all(isinstance(p, list) for p in case["world"]["free"])
    case = example_layouts.l_corridor(1.5)
    out = tmp_path / "map.png"
    save_diagnostic(
        out, World.from_dict(case["world"]), case["start"], case["goal"], Train.uniform(3)
    )
    assert out.stat().st_size > 1000 and out.read_bytes()[:4] == b"\x89PNG"


def test_a_failures_place_says_whether_it_is_what_blocked():
    """The failure picture's label of the widest way's narrowest passage: crimson with
    "width < needed" where it is too narrow; grey and "wide enough" where it is not (the
    l_corridor with a goal the train cannot take: the 2 m corridor was ringed as a
    bottleneck); a corner too tight keeps its own words and its need."""
    from pushtrain.planner.diagnostic import place_label

    label, note, color = place_label({"what": "bottleneck", "x": 0, "y": 0, "width": 0.55,
                                      "needed": 0.70})
    assert color == "crimson" and note == "0.55 m < 0.70 m" and "bottleneck: 0.55 m" in label
    label, note, color = place_label({"what": "bottleneck", "x": 0, "y": 0, "width": 2.0,
                                      "needed": 0.70})
    assert color != "crimson" and "wide enough" in label and note == "2.00 m"
    label, note, color = place_label({"what": "corner too tight (90 deg turn, 0.76 m swept)",
                                      "x": 0, "y": 0, "width": 1.1, "needed": None})
    assert color == "crimson" and "no steady turn fits" in label and note == "1.10 m"
