"""Cost-to-go estimates: the map's own distance, Reeds-Shepp length, the car among the walls."""

import math

import pytest

from pushtrain.facility import example_layouts
from pushtrain.facility.free_space import World
from pushtrain.planner.heuristic import Heuristic
from pushtrain.planner.reeds_shepp import rs_distance


def test_grid_distance_goes_around_the_corner():
    case = example_layouts.l_corridor(2.0)
    world = World.from_dict(case["world"])
    h = Heuristic(world.distance_field(), case["goal"], 1.0, 0.35, car_resolution=None)
    # the shortest way of a point keeping 0.35 m from the walls: to the inner corner moved by
    # 0.35 m in both directions, then on to the goal (computed here by hand)
    corner = (7.0 + 0.35, 2.0 - 0.35)
    sx, sy = case["start"][:2]
    gx, gy = case["goal"][:2]
    geodesic = math.dist((sx, sy), corner) + math.dist(corner, (gx, gy))
    assert math.dist((sx, sy), (gx, gy)) < geodesic - 0.1  # the straight line cuts the wall
    # 8-connected grid paths are at most 8 % longer than the straight ones
    assert geodesic <= h.grid(sx, sy) <= 1.09 * geodesic
    assert h.grid(gx, gy) == pytest.approx(0.0, abs=0.05)


def test_a_node_cap_coarsens_the_grid_and_keeps_it_a_lower_bound_of_the_way():
    """max_nodes (a short time budget) gives a grid of about that many nodes whose distance
    still goes around the corner and stays within the 8-connected bound."""
    case = example_layouts.l_corridor(2.0)
    world = World.from_dict(case["world"])
    field = world.distance_field()
    fine = Heuristic(field, case["goal"], 1.0, 0.35, car_resolution=None)
    coarse = Heuristic(field, case["goal"], 1.0, 0.35, car_resolution=None, max_nodes=2000)
    assert coarse.free.size <= 1.05 * 2000 < fine.free.size  # (nx + 1)(ny + 1) nodes
    assert coarse.resolution > fine.resolution
    sx, sy = case["start"][:2]
    corner = (7.0 + 0.35, 2.0 - 0.35)
    geodesic = math.dist((sx, sy), corner) + math.dist(corner, case["goal"][:2])
    # the coarse grid lets a point pass up to h / sqrt(2) closer to the corner
    slack = 2.0 * coarse.resolution
    assert geodesic - slack <= coarse.grid(sx, sy) <= 1.09 * geodesic


def test_rs_is_the_reeds_shepp_length_of_the_chain_poses():
    case = example_layouts.bay()
    world = World.from_dict(case["world"])
    h = Heuristic(world.distance_field(), case["goal"], 0.9, 0.35, car_resolution=None)
    start, goal = case["start"], case["goal"]
    expected = rs_distance(0.9, (start[0], start[1], start[2] + math.pi),
                           (goal[0], goal[1], goal[2] + math.pi))
    assert h.rs(start) == pytest.approx(expected, rel=1e-9)


def test_separated_rooms_have_no_finite_estimate():
    case = example_layouts.two_rooms(0.5)  # a slit narrower than the trailer's 0.7 m band
    world = World.from_dict(case["world"])
    h = Heuristic(world.distance_field(), case["goal"], 1.0, 0.35)
    assert h(case["start"]) == math.inf
    assert h((case["goal"][0] - 1.0, case["goal"][1], case["goal"][2])) < 1.5


def test_the_car_turns_around_only_where_there_is_room():
    """In the T-junction a train heading the wrong way must turn in the side branch: the car's
    cost is far above the Reeds-Shepp length (which turns on the spot through the walls) and
    above the distance, and it charges a cusp."""
    case = example_layouts.t_junction()
    world = World.from_dict(case["world"])
    h = Heuristic(world.distance_field(), case["goal"], 0.97, 0.35)
    wrong_way = (1.0, 1.0, math.pi)  # pushing toward +x, the goal wants the robot toward +x
    right_way = (1.0, 1.0, 0.0)
    assert h.car(wrong_way) > h.rs(wrong_way) + 2.0
    assert h.car(wrong_way) > h.grid(1.0, 1.0) + 2.0  # at least a cusp (2.0) on top
    # pulled the right way 1.5 m short of the goal: about 1.5 m at the pull price 1.2
    assert h.car(right_way, -1) == pytest.approx(1.5 * 1.2, abs=0.5)  # the goal: +-1 cell
    assert h(right_way, -1) >= h.car(right_way, -1)
