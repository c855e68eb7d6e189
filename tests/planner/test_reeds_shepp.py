"""The Reeds-Shepp paths computed from the closed-form words, against OMPL's own distance and
interpolation (C++), and against integrating their pieces to the goal."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pushtrain.core.reference import Reference
from pushtrain.core.segment import PULL, PUSH
from pushtrain.planner.reeds_shepp import (
    Primitive,
    ReedsSheppCurve,
    advance_yaw,
    evaluate_primitives,
    primitives_to_segments,
    rs_segments,
    shortest_path,
)


def _angle(a):
    return np.abs(np.angle(np.exp(1j * np.asarray(a))))


def _end_error(a, b, pieces, rho):
    """Position [m] and heading [rad] error at the end of the pieces, integrated from ``a``."""
    end = evaluate_primitives(a, pieces, rho, [sum(p.length for p in pieces)])[0]
    return math.hypot(end[0] - b[0], end[1] - b[1]), float(_angle(end[2] - b[2]))


pose = st.tuples(st.floats(-20.0, 20.0), st.floats(-20.0, 20.0), st.floats(-4.0, 4.0))


@settings(max_examples=400, deadline=None)
@given(a=pose, b=pose, rho=st.floats(0.2, 3.0))
def test_the_path_is_ompls_shortest_and_ends_at_the_goal(a, b, rho):
    path = shortest_path(rho, a, b)
    curve = ReedsSheppCurve(rho, a, b)
    assert path.length == pytest.approx(curve.length, rel=1e-12, abs=1e-12)
    pieces = path.primitives()
    assert len(pieces) <= 5
    assert sum(p.length for p in pieces) == pytest.approx(path.length, rel=1e-12, abs=1e-12)
    assert max(_end_error(a, b, pieces, rho)) < 1e-9
    ts = np.linspace(0.0, 1.0, 17)
    ompl = np.array([curve.interpolate(t) for t in ts])
    ours = evaluate_primitives(a, pieces, rho, ts * path.length)
    assert np.hypot(*(ours[:, :2] - ompl[:, :2]).T).max() < 1e-9
    assert _angle(ours[:, 2] - ompl[:, 2]).max() < 1e-9


@pytest.mark.parametrize("rho", [0.5, 0.975, 2.0])
def test_every_word_is_found_and_the_reference_follows_ompls_curve(rho):
    """Over random pose pairs every one of the 18 words is the shortest somewhere, and the
    co-simulation's reference built from the segments follows OMPL's interpolation."""
    rng = np.random.default_rng(int(rho * 1000))
    words, worst = set(), 0.0
    for k in range(1500):
        scale = rng.choice([0.3 * rho, 2.0 * rho, 8.0 * rho])
        a = (*rng.uniform(-scale, scale, 2), rng.uniform(-math.pi, math.pi))
        b = (*rng.uniform(-scale, scale, 2), rng.uniform(-math.pi, math.pi))
        path = shortest_path(rho, a, b)
        words.add(path.word)
        if len(words) < 18 or k % 10 == 0:
            curve = ReedsSheppCurve(rho, a, b)
            ts = np.linspace(0.0, 1.0, 33)
            ompl = np.array([curve.interpolate(t) for t in ts])
            segs = primitives_to_segments(path.primitives(), rho)
            ref = Reference.from_segments((a[0], a[1], a[2] + math.pi), segs, speed=1.0,
                                          cusp_dwell=0.0)
            x, y, th, _, _ = ref.sample(ts * curve.length)
            worst = max(worst, float(np.hypot(x - ompl[:, 0], y - ompl[:, 1]).max()))
            assert _angle(th - math.pi - ompl[:, 2]).max() < 1e-6
    assert len(words) == 18, sorted(words)
    assert worst < 1e-6


def test_a_reversal_far_shorter_than_a_micrometre_is_left_out():
    """OMPL's curve from this pose of the docking example (RLSL) starts with 6.5e-8 m of right
    arc backward before turning left forward and ends with 5.8e-8 m of left arc; the planner's
    segments leave those pieces out and are the left arc and the line, which end within a
    micrometre of the goal."""
    rho = 0.9728515741304826
    a = (9.027148581393263, 1.2499999999999996, 0.0)
    b = (9.999999880140784, 4.399999998462434, 4.712389106872607 + math.pi)
    path = shortest_path(rho, a, b)
    assert path.word == "RLSL"
    tiny = [p for p in path.primitives() if p.length < 1e-6]
    assert [(p.turn, p.gear) for p in tiny] == [("R", -1), ("L", 1)]
    assert min(p.length for p in tiny) > 1e-8
    assert max(_end_error(a, b, path.primitives(), rho)) < 1e-9
    segments = rs_segments((a[0], a[1], a[2] - math.pi), (b[0], b[1], b[2] - math.pi), rho)
    assert [(g.kind, g.direction) for g in segments] == [("arc", PUSH), ("line", PUSH)]
    ref = Reference.from_segments((a[0], a[1], a[2] - math.pi), segments)
    assert math.hypot(ref.goal[0] - b[0], ref.goal[1] - b[1]) < 1e-6


@pytest.mark.parametrize("rho", [1e-6, 1e-4])
def test_a_tiny_radius_gives_turn_straight_turn_to_the_goal(rho):
    a, b = (0.0, 0.0, 0.0), (8.0, 3.0, 1.0)
    path = shortest_path(rho, a, b)
    assert path.length == pytest.approx(ReedsSheppCurve(rho, a, b).length, rel=1e-12)
    pieces = path.primitives()
    assert [p.turn for p in pieces][1] == "S" and pieces[1].length > 8.5
    assert max(_end_error(a, b, pieces, rho)) < 1e-9


def test_a_long_curve_follows_ompl():
    rho = 0.5
    a, b = (0.0, 0.0, 0.3), (300.0, 250.0, -2.0)
    path = shortest_path(rho, a, b)
    curve = ReedsSheppCurve(rho, a, b)
    ts = np.linspace(0.0, 1.0, 801)
    ompl = np.array([curve.interpolate(t) for t in ts])
    ours = evaluate_primitives(a, path.primitives(), rho, ts * curve.length)
    assert np.hypot(*(ours[:, :2] - ompl[:, :2]).T).max() < 1e-9
    assert _angle(ours[:, 2] - ompl[:, 2]).max() < 1e-9


def test_non_finite_poses_give_no_connection():
    assert rs_segments((0.0, 0.0, 0.0), (math.nan, 1.0, 0.0), 1.0) is None
    assert rs_segments((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 1.0) == []


def test_direction_and_curvature_conventions():
    rho = 1.0
    prims = [Primitive("L", 1, 0.5), Primitive("R", -1, 0.7), Primitive("S", -1, 1.0)]
    segs = primitives_to_segments(prims, rho)
    assert [g.direction for g in segs] == [PUSH, PULL, PULL]
    # L forward: yaw grows; R backward: yaw grows too (dtheta/ds = +1/rho)
    assert segs[0].curvature == pytest.approx(1.0)
    assert segs[1].curvature == pytest.approx(1.0)
    assert segs[2].kind == "line"
    # forward primitive moves along yaw, which is theta + pi: pushing in the chain frame
    x, y, yaw = advance_yaw(0.0, 0.0, 0.0, "S", 1, 2.0, rho)
    assert (float(x), float(y)) == pytest.approx((2.0, 0.0))
    ref = Reference.from_segments(
        (0.0, 0.0, math.pi), primitives_to_segments([Primitive("S", 1, 2.0)], rho)
    )
    assert ref.goal[:2] == pytest.approx([2.0, 0.0])
    assert ref.sample([1.0])[3][0] < 0.0  # pushing: v < 0 in the chain frame
