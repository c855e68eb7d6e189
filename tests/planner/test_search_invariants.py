"""Tests that catch single-line bugs planted in the planner and the master (issue #29): each
checks behaviour against an expectation worked out independently (by hand, with shapely, from a
docstring's promise), so a plausible one-line slip in the code fails it.

- the search's cost (``segments_cost``) counting cusps and curvature changes on every segment,
- the goal tests of both propagators and of the Python master needing the heading too,
- the perimeter tier of the body check keeping the half spacing between samples,
- the work budget being spent when the work used reaches the limit.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.kinematics import body_positions
from pushtrain.core.reference import Reference
from pushtrain.core.segment import PULL, PUSH, Segment
from pushtrain.facility.free_space import World
from pushtrain.planner.config import TrackerConfig
from pushtrain.planner.footprint import body_samples, first_failure
from pushtrain.planner.lattice_settings import LatticeSettings, segments_cost
from pushtrain.planner.propagate import Cursor, Propagator
from pushtrain.planner.train import Train

# ------------------------------------------------------------------------------- the search cost
SETTINGS = LatticeSettings(radius=1.0, turn_weight=0.3, pull_turn_weight=1.0, change_weight=0.25,
                          cusp_cost=2.0, pull_factor=1.2)
PATH = [Segment("line", 1.0, 0.0, PUSH),    # 1.0
        Segment("arc", 1.0, 1.0, PUSH),     # 1.0 + 0.3 x 1 rad turned + a curvature change
        Segment("line", 1.0, 0.0, PULL),    # 1.2 pulled + a cusp + a curvature change
        Segment("arc", 0.5, -0.5, PULL),    # 0.6 + 1.0 x 0.25 rad + a curvature change
        Segment("line", 0.5, 0.0, PUSH)]    # 0.5 + a cusp + a curvature change


def test_the_search_cost_counts_every_cusp_and_curvature_change():
    by_hand = (1.0 + 1.0 + 0.3 * 1.0 + 0.25
               + 1.2 + 2.0 + 0.25
               + 0.6 + 1.0 * 0.25 + 0.25
               + 0.5 + 2.0 + 0.25)
    assert segments_cost(PATH, SETTINGS) == pytest.approx(by_hand, abs=1e-12)
    # after a pull on an arc of curvature -0.5 the first push is one more cusp and change
    assert segments_cost(PATH, SETTINGS, PULL, -0.5) == pytest.approx(by_hand + 2.0 + 0.25,
                                                                      abs=1e-12)
    # the same pieces without cusps and changes cost their lengths and turns alone
    plain = [Segment("line", 2.0, 0.0, PUSH)]
    assert segments_cost(plain * 3, SETTINGS) == pytest.approx(6.0, abs=1e-12)


# ----------------------------------------------------------------------------------- goal tests
TRAIN = Train.uniform(3)
CONTROLLER = ControllerConfig(geometry=TRAIN.geometry)
OPEN = World.from_dict({"bounds": [-8, -8, 8, 8]})
START = (0.0, 0.0, math.pi)
LINE = [Segment("line", 1.0)]
TOLERANCE = (0.05, math.radians(5.0))


def test_the_search_goal_test_needs_the_heading():
    """The rollout ends on the reference's end point with the reference's heading; a goal at
    that point turned by 20 deg is missed (heading error 20 deg > 5 deg), the true one is
    reached."""
    tracker = TrackerConfig(controller=CONTROLLER, goal_tolerance=TOLERANCE)
    prop = Propagator(TRAIN, CONTROLLER, tracker, OPEN.distance_field(),
                      body_samples(TRAIN, 0.0), TRAIN.phi_max)
    state = prop.initial_state(START, np.full(4, math.pi))
    end = Reference.from_segments(START, LINE, tracker.speed, 1.0).goal
    reached = prop.rollout(state, Cursor(*START, 0.0, 0), LINE, goal=end)
    assert reached.ok and reached.goal_error[1] < TOLERANCE[1]
    turned = (end[0], end[1], end[2] + math.radians(20.0))
    missed = prop.rollout(state, Cursor(*START, 0.0, 0), LINE, goal=turned)
    assert not missed.ok and missed.failure["kind"] == "goal_missed"
    assert missed.failure["distance"] <= TOLERANCE[0]  # the position alone would pass
    assert missed.failure["heading_error"] == pytest.approx(math.radians(20.0), abs=0.02)


class _TurnedGoal(Reference):
    """A line whose goal is its end point with the heading turned by ``turn`` [rad]."""

    turn = math.radians(20.0)

    @property
    def goal(self):
        x, y, theta = super().goal
        return np.array([x, y, theta + self.turn])


def test_the_masters_goal_test_needs_the_heading(fmu3):
    """The master's goal test (a candidate in C, then Python's exact test): the last trailer
    ends on the goal's point with the line's heading, 20 deg from the goal's: never reached."""
    from pushtrain.core.controller import ControllerConfig
    from pushtrain.cosim.master import simulate

    ref = _TurnedGoal.from_segments(START, LINE, speed=0.08, cusp_dwell=1.0)
    kwargs = dict(settle_time=5.0, goal_tolerance=TOLERANCE)
    result = simulate(fmu3, ref, ControllerConfig.uniform(3), **kwargs)
    assert result.status != "goal_reached", result.message
    d = result.data
    end = np.array(Reference.from_segments(START, LINE, speed=0.08).goal)
    assert math.hypot(d["x3"][-1] - end[0], d["y3"][-1] - end[1]) < TOLERANCE[0]
    straight = Reference.from_segments(START, LINE, speed=0.08, cusp_dwell=1.0)
    assert simulate(fmu3, straight, ControllerConfig.uniform(3), **kwargs).status \
        == "goal_reached"


# ---------------------------------------------------------------------------- the body check
def test_a_wall_between_two_perimeter_samples_is_seen():
    """A wall's corner 3 cm from a trailer's long side, midway between two perimeter samples
    0.4 m apart (each 0.2 m from it): the side keeps 0.03 m (shapely), less than its 0.05 m
    clearance, so the sampled test must refuse it; the samples alone keep 0.20 m, so only their
    half-spacing allowance (margin + s/2 + tol) sees it."""
    train = Train.uniform(1)
    z = np.array([[2.0, 0.0, 0.0, 0.0]])  # robot at (2, 0), all headings +x
    x, y = body_positions(z[:, 0], z[:, 1], z[:, 2:], train.geometry)
    ax, ay = x[0, 1], y[0, 1]  # the trailer's axle midpoint; its side y = ay - 0.3
    tip = (ax + 0.2, ay - 0.3 - 0.03)
    wedge = [tip, (tip[0] - 0.5, tip[1] - 1.0), (tip[0] + 0.5, tip[1] - 1.0)]
    world = World.from_dict({"bounds": [-6, -6, 6, 6], "obstacles": [wedge]})
    trailer = shapely.geometry.Polygon(train.bodies[1].polygons(ax, ay, 0.0))
    gap = trailer.distance(shapely.geometry.Polygon(wedge))
    assert gap == pytest.approx(0.03, abs=1e-9)
    samples = body_samples(train, 0.05, spacing=0.4)
    assert set(np.round(samples.u[(samples.body == 1) & (np.abs(samples.v + 0.3) < 1e-9)], 9)) \
        == {-0.4, 0.0, 0.4}  # the side's samples: the tip at u = 0.2 is 0.2 m from two
    failure, _ = first_failure(train, world.distance_field(), samples, z, train.phi_max)
    assert failure is not None and failure["kind"] == "collision" and failure["body"] == 1
    # the same wedge half a metre further out: the trailer is clear (the test is not one that
    # refuses everything near a wall)
    ok_world = World.from_dict({"bounds": [-6, -6, 6, 6], "obstacles": [
        [(px, py - 0.5) for px, py in wedge]]})
    far, _ = first_failure(train, ok_world.distance_field(), samples, z, train.phi_max)
    assert far is None


# --------------------------------------------------------------------------------- the budget
def test_the_work_budget_is_spent_when_the_work_reaches_the_limit():
    """``Work.done``: "True once used reaches limit" (planner/budget.py)."""
    from pushtrain.planner.budget import Work

    assert not Work(used=9).done(10)
    assert Work(used=10).done(10)
    assert Work(used=11).done(10)
    assert not Work(used=0).done(1) and Work(used=1).done(1)
    assert not Work(used=10).capped  # the work, not the clock, stopped it
