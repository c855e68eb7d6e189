"""Whole-train model: agreement with cosim.kinematics, pushing and pulling stretches."""

import math

import numpy as np
import pytest

from pushtrain.cosim.kinematics import (
    ChainGeometry,
    body_positions_from_last,
    heading_rates_from_last,
    steady_joint_angle,
)
from pushtrain.cosim.reference import PULL, PUSH, Segment
from pushtrain.planner import Train, World, check_train
from pushtrain.planner.train_check import body_positions_along, chain_heading_rates


def test_fast_rates_match_kinematics():
    rng = np.random.default_rng(1)
    geom = ChainGeometry(rng.uniform(0.3, 0.8, 4), rng.uniform(0.3, 0.8, 4))
    rates = chain_heading_rates(geom)
    for _ in range(50):
        th = rng.uniform(-3, 3, 5)
        v, w = rng.uniform(-1, 1, 2)
        assert np.allclose(rates(list(th), v, w), heading_rates_from_last(th, v, w, geom))


def test_positions_match_kinematics():
    rng = np.random.default_rng(2)
    geom = ChainGeometry.uniform(3)
    th = rng.uniform(-3, 3, (6, 4))
    poses = np.column_stack([rng.uniform(-5, 5, (6, 2)), th[:, -1]])
    x, y = body_positions_along(poses, th, geom)
    for k in range(6):
        ex, ey = body_positions_from_last(poses[k, 0], poses[k, 1], th[k], geom)
        assert np.allclose(x[k], ex) and np.allclose(y[k], ey)


def test_pushing_on_a_long_arc_reaches_the_steady_joint_angle():
    train = Train.uniform(3)
    world = World.from_dict({"bounds": [-20, -20, 20, 20]})
    r = 2.5
    res = check_train(world, train, (0, 0, 0), [Segment("arc", 3 * math.pi * r, 1 / r, PUSH)])
    phi_end = np.abs(np.angle(np.exp(1j * (res.headings[-1, :-1] - res.headings[-1, 1:]))))
    assert phi_end == pytest.approx(steady_joint_angle(r, 0.52), abs=1e-3)


def test_straight_pull_keeps_a_straight_chain_on_the_line():
    train = Train.uniform(3)
    world = World.from_dict({"bounds": [-20, -20, 20, 20]})
    res = check_train(world, train, (0, 0, 0.3), [Segment("line", 4.0, 0.0, PULL)])
    assert res.ok
    assert res.pulls[0]["end_error"] < 1e-6 and res.pulls[0]["max_deviation"] < 1e-6
    assert np.abs(res.headings - 0.3).max() < 1e-9


def test_collision_is_reported_with_body_and_place():
    train = Train.uniform(3)
    # corridor 1.0 m wide; a 90 deg turn with r = 1 m makes the bodies hit the wall
    world = World.from_dict({"free": [[-10, -0.5], [10, -0.5], [10, 0.5], [-10, 0.5]]})
    res = check_train(world, train, (0, 0, math.pi),
                      [Segment("line", 1.0, 0.0, PUSH), Segment("arc", 1.0, 1.0, PUSH)])
    assert not res.ok and res.failure["kind"] == "collision"
    assert res.failure["y"] > 0.45 or res.failure["y"] < -0.45
