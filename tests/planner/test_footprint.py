"""The whole train against the distance field: sampled clearance never passes what the exact
geometry refuses, self-collision against shapely, the joint limit."""

import math

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Polygon

from pushtrain.facility import example_layouts
from pushtrain.facility.free_space import World
from pushtrain.planner.footprint import _obb_overlap, body_samples, first_failure
from pushtrain.planner.train import BodyFootprint, Train

TRAIN = Train.uniform(3)
DOCK = World.from_dict(example_layouts.docking_bay()["world"])
FIELD = DOCK.distance_field()
SAMPLES = body_samples(TRAIN, 0.05)


def _train_state(x0, y0, headings):
    return np.array([[x0, y0, *headings]])


def _exact_gaps(world, train, z):
    """Distance [m] of every body to the walls (shapely), negative if it leaves the free space."""
    from pushtrain.core.kinematics import body_positions

    x, y = body_positions(z[:, 0], z[:, 1], z[:, 2:], train.geometry)
    out = []
    for i, body in enumerate(train.bodies):
        poly = body.polygons(x[0, i], y[0, i], z[0, 2 + i])
        gap = world.free.boundary.distance(poly)
        out.append(gap if world.free.covers(poly) else -gap)
    return np.array(out)


@settings(max_examples=300, deadline=None)
@given(x=st.floats(8.5, 11.5), y=st.floats(0.3, 4.7), th=st.floats(-math.pi, math.pi),
       bend=st.lists(st.floats(-0.6, 0.6), min_size=3, max_size=3))
def test_a_sampled_pass_is_an_exact_pass(x, y, th, bend):
    """Wherever the sampled test passes, every body keeps its clearance exactly (shapely)."""
    headings = th + np.concatenate((np.cumsum(np.array(bend)[::-1])[::-1], [0.0]))
    z = _train_state(x, y, headings)
    failure, _ = first_failure(TRAIN, FIELD, SAMPLES, z, math.pi)
    gaps = _exact_gaps(DOCK, TRAIN, z)
    if failure is None:
        assert gaps.min() >= 0.05 - 1e-9
    # and it is conservative by at most half the spacing plus the field's tolerance
    if gaps.min() >= 0.05 + 0.5 * 0.025 + 0.002 + 0.002:
        assert failure is None or failure["kind"] != "collision"


def test_a_trailer_in_the_bay_with_its_clearance_passes_and_closer_fails():
    case = example_layouts.docking_bay()
    gx, gy, gth = case["goal"]
    # the last trailer centred in the 0.9 m bay keeps 0.15 m on each side
    fp = TRAIN.last
    samples = body_samples(Train(TRAIN.geometry, TRAIN.robot, (fp,) * 3, TRAIN.phi_max), 0.05)
    last = samples.body == 3
    for dx, ok in ((0.0, True), (0.08, True), (0.11, False)):
        c, s = math.cos(gth), math.sin(gth)
        px = gx + dx + samples.u[last] * c - samples.v[last] * s
        py = gy + samples.u[last] * s + samples.v[last] * c
        passed = bool((FIELD.at(px, py) >= samples.threshold[last]).all())
        assert passed == ok, dx


def test_a_pillar_inside_a_body_is_found():
    """An obstacle smaller than the trailer, wholly inside it, is seen by the interior points."""
    world = World.from_dict({"bounds": [-4, -4, 4, 4],
                             "obstacles": [[[-0.1, -0.1], [0.1, -0.1], [0.1, 0.1], [-0.1, 0.1]]]})
    field = world.distance_field()
    train = Train.uniform(1)
    samples = body_samples(train, 0.05)
    # trailer 1 centred on the pillar, robot far away along the chain
    z = np.array([[1.04, 0.0, 0.0, 0.0]])
    failure, _ = first_failure(train, field, samples, z, math.pi)
    assert failure is not None and failure["kind"] == "collision" and failure["body"] == 1
    # the perimeter samples alone see nothing: the pillar is 0.2 m inside the edges
    perim = (samples.body == 1) & (samples.threshold == samples.threshold[samples.body == 1].min())
    assert (field.at(samples.u[perim], samples.v[perim]) > 0.1).all()


@settings(max_examples=200, deadline=None)
@given(xa=st.floats(-1, 1), ya=st.floats(-1, 1), ta=st.floats(-math.pi, math.pi),
       xb=st.floats(-1, 1), yb=st.floats(-1, 1), tb=st.floats(-math.pi, math.pi))
def test_rectangle_overlap_equals_shapely(xa, ya, ta, xb, yb, tb):
    a, b = BodyFootprint(0.8, 0.6, 0.1), BodyFootprint(0.6, 0.5, -0.05)
    pa, pb = Polygon(a.corners(xa, ya, ta)), Polygon(b.corners(xb, yb, tb))
    if abs(pa.distance(pb)) < 1e-9 and not pa.intersection(pb).area > 1e-9:
        return  # touching: either answer is right
    expected = pa.intersection(pb).area > 1e-9
    got = bool(_obb_overlap(a, b, np.array(xa), np.array(ya), np.array(ta), np.array(xb),
                            np.array(yb), np.array(tb)))
    assert got == expected


def test_a_folded_train_collides_with_itself_and_the_joint_limit():
    open_world = World.from_dict({"bounds": [-4, -4, 4, 4]})
    field = open_world.distance_field()
    train = Train.uniform(3)
    samples = body_samples(train, 0.0)
    # robot and trailer 2 folded onto each other: two joints of 120 deg (with D = 0.52 m,
    # joints of 90 deg keep them 1.04 m apart)
    th = np.radians([0.0, -120.0, -240.0, -240.0])
    failure, _ = first_failure(train, field, samples, np.array([[0.0, 0.0, *th]]), math.pi)
    assert failure["kind"] == "self_collision"
    from pushtrain.core.kinematics import body_positions

    x, y = body_positions(0.0, 0.0, np.array([th]), train.geometry)
    polys = [b.polygons(x[0, i], y[0, i], th[i]) for i, b in enumerate(train.bodies)]
    assert shapely.intersects(polys[failure["body"]], polys[failure["other"]])
    assert failure["other"] >= failure["body"] + 2
    straight = np.zeros(4)
    assert first_failure(train, field, samples, np.array([[0.0, 0.0, *straight]]),
                         math.pi)[0] is None
    bent = np.radians([0.0, 0.0, 0.0, -60.0])
    failure, _ = first_failure(train, field, samples, np.array([[0.0, 0.0, *bent]]),
                               math.radians(50.0))
    assert failure["kind"] == "joint_limit" and failure["body"] == 3
    assert failure["phi"] == pytest.approx(math.radians(60.0))
