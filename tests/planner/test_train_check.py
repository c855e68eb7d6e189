"""Closed-loop whole-train check: agreement with core.kinematics and with an independent loop,
tracking on lines and arcs, collisions, joint limits, the goal test, and a plan that the
open-loop model (last trailer exactly on the path) passes but the closed loop does not."""

import math

import numpy as np
import pytest
from reference.closed_loop import towed_rates
from reference.controller import BackwardController
from scipy.integrate import solve_ivp
from shapely.ops import unary_union

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.kinematics import (
    ChainGeometry,
    body_positions,
    forward_velocities,
    heading_rates_from_last,
    joint_angles,
    steady_joint_angle,
)
from pushtrain.core.reference import Reference
from pushtrain.core.segment import PULL, PUSH, Segment
from pushtrain.errors import PlanningInputError
from pushtrain.facility.free_space import World
from pushtrain.planner.config import TrackerConfig
from pushtrain.planner.path import reference_times
from pushtrain.planner.train import Train
from pushtrain.planner.train_check import check_train

TRAIN = Train.uniform(3)
OPEN = World.from_dict({"bounds": [-50, -50, 50, 50]})


class _Meas:
    def __init__(self, x0, y0, th):
        self.x0, self.y0, self.theta0 = x0, y0, th[0]
        self.phi = list(th[:-1] - th[1:])


def _independent_loop(geom, reference, theta0, config, h=0.002, settle=2.0):
    """The controller at every h with forward Euler on kinematics.forward_velocities (numpy);
    returns times and the last trailer's positions (K, 2)."""
    ctrl = BackwardController(config)
    ctrl.reset(0.0, 0.0, -h)
    th = np.array(theta0, dtype=float)
    bx, by = body_positions(*reference.start[:2], th, geom, from_last=True)
    x0, y0 = bx[0], by[0]
    steps = int(math.ceil((reference.t_end + settle) / h))
    out = np.empty((steps + 1, 2))
    for k in range(steps + 1):
        bx, by = body_positions(x0, y0, th, geom)
        out[k] = bx[-1], by[-1]
        v0, w0, _ = ctrl.command_from(reference, k * h, _Meas(x0, y0, th))
        _, w = forward_velocities(joint_angles(th), v0, w0, geom)
        x0, y0 = x0 + h * v0 * math.cos(th[0]), y0 + h * v0 * math.sin(th[0])
        th = th + h * w
    return h * np.arange(steps + 1), out


def test_towed_rates_match_kinematics():
    rng = np.random.default_rng(1)
    geom = ChainGeometry(rng.uniform(0.3, 0.8, 4), rng.uniform(0.3, 0.8, 4))
    rates = towed_rates(geom)
    for _ in range(50):
        th = rng.uniform(-3, 3, 5)
        v, w = rng.uniform(-1, 1, 2)
        expected = forward_velocities(joint_angles(th), v, w, geom)[1]
        assert np.allclose(rates(list(th), v, w), expected)


def test_positions_match_kinematics():
    rng = np.random.default_rng(2)
    geom = ChainGeometry.uniform(3)
    th = rng.uniform(-3, 3, (6, 4))
    poses = np.column_stack([rng.uniform(-5, 5, (6, 2)), th[:, -1]])
    x, y = body_positions(poses[:, 0], poses[:, 1], th, geom, from_last=True)
    for k in range(6):
        ex, ey = body_positions(poses[k, 0], poses[k, 1], th[k], geom, from_last=True)
        assert np.allclose(x[k], ex) and np.allclose(y[k], ey)


def test_closed_loop_matches_an_independent_fine_euler_loop():
    # a cusp, arcs and a bent start: large transients (tracking errors of several cm)
    segs = [Segment("line", 0.6, 0.0, PUSH), Segment("arc", 1.2, 1 / 1.2, PUSH),
            Segment("arc", 0.8, -1 / 1.5, PULL), Segment("line", 0.6, 0.0, PULL)]
    start = (0.0, 0.0, math.pi)
    theta0 = math.pi + np.array([0.5, 0.3, 0.15, 0.0])
    # (ending on a short pull, the towed last trailer misses the goal: not tested here)
    res = check_train(OPEN, TRAIN, start, segs, theta0, tracker=TrackerConfig(goal_tolerance=None))
    assert res.ok, res.failure
    assert res.max_tracking_error > 0.05  # not a trivial run
    ref = Reference.from_segments(start, segs, 0.08, 1.0)
    t, last = _independent_loop(TRAIN.geometry, ref, theta0,
                                ControllerConfig(geometry=TRAIN.geometry))
    tr = res.run
    z = tr.states
    x, y = body_positions(0.0, 0.0, z[:, 2:], TRAIN.geometry, from_last=True)
    # positions relative to the last trailer -> shift by the robot's position
    lx = z[:, 0] - x[:, 0] + x[:, -1]
    ly = z[:, 1] - y[:, 0] + y[:, -1]
    err = np.hypot(lx - np.interp(tr.t, t, last[:, 0]), ly - np.interp(tr.t, t, last[:, 1]))
    assert err.max() < 0.01
    # the result's last-trailer poses are the same trajectory
    assert np.allclose(np.interp(res.t, tr.t, lx), res.poses[:, 0], atol=2e-3)


def test_step_size_converges():
    segs = [Segment("arc", 1.0, 1 / 0.97, PULL), Segment("line", 1.0, 0.0, PULL),
            Segment("arc", 1.5, 1 / 0.97, PUSH), Segment("line", 1.0, 0.0, PUSH)]
    start = (0.0, 0.0, math.pi)
    runs = {h: check_train(OPEN, TRAIN, start, segs, tracker=TrackerConfig(step=h)).run
            for h in (0.025, 0.0025)}
    coarse, fine = runs[0.025], runs[0.0025]

    def last(tr):
        z = tr.states
        x, y = body_positions(0.0, 0.0, z[:, 2:], TRAIN.geometry, from_last=True)
        return z[:, 0] - x[:, 0] + x[:, -1], z[:, 1] - y[:, 0] + y[:, -1]

    (xc, yc), (xf, yf) = last(coarse), last(fine)
    err = np.hypot(xc - np.interp(coarse.t, fine.t, xf), yc - np.interp(coarse.t, fine.t, yf))
    assert err.max() < 0.01


def test_straight_push_lags_by_the_acceleration_ramp_only():
    res = check_train(OPEN, TRAIN, (0, 0, math.pi), [Segment("line", 2.0, 0.0, PUSH)])
    assert res.ok
    # robot starts at rest, acc_max = 0.2 m/s²: when it reaches 0.08 m/s (t = 0.4 s) the
    # last trailer lags 0.08 * 0.4 - 0.2 * 0.4² / 2 = 0.016 m behind the reference
    assert res.max_tracking_error == pytest.approx(0.016, abs=2e-3)
    assert res.max_lateral_error < 1e-9 and res.max_heading_error < 1e-9
    assert np.abs(res.headings - math.pi).max() < 1e-9
    assert res.goal_error[0] < 0.05


def test_straight_pull_keeps_a_straight_chain_on_the_line():
    res = check_train(OPEN, TRAIN, (0, 0, 0.3), [Segment("line", 3.0, 0.0, PULL)])
    assert res.ok
    assert res.max_lateral_error < 1e-9
    assert np.abs(res.headings - 0.3).max() < 1e-9
    # the robot leads: it moves along theta = 0.3, toward the robot side
    d = res.poses[-1, :2] - res.poses[0, :2]
    assert d @ np.array([math.cos(0.3), math.sin(0.3)]) == pytest.approx(3.0, abs=0.05)


def test_pushing_on_a_long_arc_reaches_the_steady_joint_angle():
    r = 2.5
    res = check_train(OPEN, TRAIN, (0, 0, 0), [Segment("arc", 2 * math.pi * r, 1 / r, PUSH)])
    assert res.ok
    k = np.searchsorted(res.t, 0.9 * 2 * math.pi * r / 0.08)
    phi = np.abs(joint_angles(res.headings[k]))
    assert phi == pytest.approx(steady_joint_angle(r, 0.52), abs=2e-3)
    assert res.max_abs_phi.max() < 1.1 * steady_joint_angle(r, 0.52)


def test_collision_is_reported_with_body_time_and_place():
    # corridor 1.0 m wide; a 90 deg turn with r = 1 m makes the bodies hit the wall
    world = World.from_dict({"free": [[-10, -0.5], [10, -0.5], [10, 0.5], [-10, 0.5]]})
    segs = [Segment("line", 1.0, 0.0, PUSH), Segment("arc", 1.0, 1.0, PUSH)]
    res = check_train(world, TRAIN, (0, 0, math.pi), segs)
    f = res.failure
    assert not res.ok and f["kind"] == "collision" and f["direction"] == PUSH
    assert f["y"] > 0.45 or f["y"] < -0.45
    assert res.min_clearance <= 0.0
    # time and reference progress agree: s = speed * t while pushing
    assert f["s"] == pytest.approx(0.08 * f["t"])
    k = int(np.searchsorted(res.t, f["t"]))
    bx, by = body_positions(res.poses[k, 0], res.poses[k, 1], res.headings[k], TRAIN.geometry,
                            from_last=True)
    i = f["body"]
    assert (bx[i], by[i]) == pytest.approx((f["body_x"], f["body_y"]), abs=1e-9)
    assert not world.free.contains(TRAIN.bodies[i].polygons(bx[i], by[i], res.headings[k, i]))


def test_joint_limit_and_missed_goal():
    train = Train.uniform(3, phi_max=math.radians(30.0))
    res = check_train(OPEN, train, (0, 0, 0), [Segment("arc", 2.0, 1 / 0.97, PUSH)])
    assert res.failure["kind"] == "joint_limit"
    assert abs(res.failure["phi"]) > math.radians(30.0)
    # a robot limited to 0.05 m/s (no rate limits) cannot keep up with a 0.08 m/s reference:
    # it covers 0.05 m/s x 12.5 s of the 1 m and stops when the reference does
    slow = TrackerConfig(controller=ControllerConfig.uniform(3, v_max=0.05), speed=0.08)
    res = check_train(OPEN, TRAIN, (0, 0, 0), [Segment("line", 1.0, 0.0, PUSH)], tracker=slow)
    assert res.failure["kind"] == "goal_missed"
    assert res.failure["distance"] == pytest.approx(1.0 - 0.05 * 12.5, abs=2e-3)
    assert check_train(OPEN, TRAIN, (0, 0, 0), [Segment("line", 1.0, 0.0, PUSH)],
                       tracker=TrackerConfig(controller=slow.controller,
                                             goal_tolerance=None)).ok


def test_checked_samples_are_dense_enough():
    segs = [Segment("arc", 1.0, 1 / 0.97, PULL), Segment("arc", 2.0, -1 / 0.97, PUSH)]
    res = check_train(OPEN, TRAIN, (0, 0, 0.0), segs, resolution=0.01)
    corners = np.stack([b.corners(res.x[:, i], res.y[:, i], res.headings[:, i])
                        for i, b in enumerate(TRAIN.bodies)], axis=1)
    step = np.linalg.norm(np.diff(corners, axis=0), axis=-1).max(axis=(1, 2))
    assert step.max() <= 0.01 + 1e-9
    assert np.all(np.diff(res.t) > 0)


def test_reference_times_follow_the_reference():
    segs = [Segment("line", 1.0, 0.0, PUSH), Segment("arc", 0.5, 1.0, PULL, speed=0.05),
            Segment("line", 0.7, 0.0, PUSH)]
    ref = Reference.from_segments((1, 2, 0.3), segs, 0.08, 1.5)
    s = np.array([0.0, 0.4, 1.0, 1.2, 1.5, 1.9, 2.2])
    t, _ = reference_times(segs, 0.08, 1.5, s)
    assert t == pytest.approx([0.0, 5.0, 12.5, 12.5 + 1.5 + 4.0, 12.5 + 1.5 + 10.0,
                               25.5 + 5.0, 25.5 + 8.75])
    # the reference is at the path pose of s at that time (path: unit speed, no dwell)
    dense = Reference.from_segments(
        (1, 2, 0.3), [Segment(g.kind, g.length, g.curvature, g.direction) for g in segs], 1.0, 0.0)
    x, y, _, _, _ = dense.sample(s)
    xr, yr, _, _, _ = ref.sample(t)
    assert np.allclose(x, xr) and np.allclose(y, yr)


def test_tracker_validation():
    with pytest.raises(PlanningInputError, match="speed"):
        TrackerConfig(speed=0.0)
    with pytest.raises(PlanningInputError, match="goal_tolerance"):
        TrackerConfig(goal_tolerance=(0.05,))
    with pytest.raises(PlanningInputError, match="n = 2"):
        check_train(OPEN, TRAIN, (0, 0, 0), [Segment("line", 1.0)],
                    tracker=TrackerConfig(controller=ControllerConfig.uniform(2)))


def _open_loop_sweep(train, start, segs, ds=0.005):
    """The old open-loop model, independently: the last trailer exactly on the path, headings
    from the inverse map (scipy); returns every body's footprints and the largest |phi|."""
    ref = Reference.from_segments(start, segs, 1.0, 0.0)
    theta, polys, pos, worst = np.full(train.n + 1, start[2]), [], 0.0, 0.0
    for seg in segs:
        sign = -1.0 if seg.direction == PUSH else 1.0
        def rates(s, th, sign=sign, kappa=seg.curvature):
            return heading_rates_from_last(th, sign, kappa, train.geometry)

        sol = solve_ivp(rates, (0.0, seg.length), theta, rtol=1e-10, atol=1e-12, dense_output=True)
        for s in np.linspace(0.0, seg.length, int(seg.length / ds) + 2):
            th = sol.sol(s)
            x, y, _, _, _ = ref.sample([pos + s])
            bx, by = body_positions(x[0], y[0], th, train.geometry, from_last=True)
            polys += [b.polygons(bx[i], by[i], th[i]) for i, b in enumerate(train.bodies)]
            worst = max(worst, float(np.abs(joint_angles(th)).max()))
        theta, pos = sol.sol(seg.length), pos + seg.length
    return polys, worst


def test_pull_then_push_into_a_bay_leaves_the_chain_straight_at_the_cusp():
    # pull straight 2.5 m, then push into a 90 deg left arc (a bay). The robot's pulling
    # reference (PullGuide) ends with the chain drawn out straight, so the closed loop stays
    # inside the open-loop sweep (last trailer exactly on the path) grown by 0.1 m. (The earlier
    # look-ahead robot aimed past the cusp along the arc's circle and hit the wall here.)
    r = 0.97
    start = (0.0, 0.0, math.pi)
    segs = [Segment("line", 2.5, 0.0, PULL), Segment("arc", 0.5 * math.pi * r, 1 / r, PUSH),
            Segment("line", 1.0, 0.0, PUSH)]
    polys, worst = _open_loop_sweep(TRAIN, start, segs)
    world = World(unary_union(polys).buffer(0.1))
    assert all(world.free.contains(p) for p in polys) and worst < TRAIN.phi_max
    res = check_train(world, TRAIN, start, segs)
    assert res.ok, res.failure
    assert res.max_tracking_error < 0.05
    tr = res.run
    cusp = np.flatnonzero(tr.direction == 0)
    cusp = cusp[(tr.t[cusp] > 1.0) & (tr.t[cusp] < 2.5 / 0.08 + 1.0)]
    assert cusp.size > 0
    phi = joint_angles(tr.states[cusp[-1], 2:])
    assert np.abs(phi).max() < math.radians(2.0)


def test_pulling_an_arc_open_loop_jackknifes_but_the_closed_loop_does_not():
    # the reverse case: the last trailer prescribed exactly on a pulling arc is the unstable
    # direction of the chain; the controller's robot leads and the towed chain is stable
    segs = [Segment("arc", 0.3, 1 / 2.0, PULL), Segment("line", 3.0, 0.0, PULL)]
    _, worst = _open_loop_sweep(TRAIN, (0, 0, 0), segs)
    assert worst > TRAIN.phi_max
    res = check_train(OPEN, TRAIN, (0, 0, 0), segs, tracker=TrackerConfig(goal_tolerance=None))
    assert res.ok and res.max_abs_phi.max() < TRAIN.phi_max / 3


@pytest.mark.parametrize("margins", [0.0, [0.05, 0.1, 0.02, 0.15]])
def test_measured_clearances_are_the_smallest_of_every_body_at_every_sample(margins):
    """The check measures only the bodies that can be the closest to a wall (bounded by the
    distance field and by how far each body moved between samples); its wall clearance and
    its clearance beyond the margins equal the minimum over every body at every checked
    sample, measured here one by one (shapely.distance to the walls)."""
    import shapely

    world = World.from_dict({"bounds": [-2, -3, 16, 3],
                             "obstacles": [[[9, -3], [10, -3], [10, -0.5], [9, -0.5]],
                                           [[4, 0.95], [4.7, 0.95], [4.7, 3], [4, 3]],
                                           [[1.0, -0.6], [1.3, -0.6], [1.3, -0.3],
                                            [1.0, -0.3]]]})
    segments = [Segment("line", 3.0, 0.0, PUSH), Segment("arc", 1.0, 0.25, PUSH),
                Segment("arc", 2.0, -0.25, PUSH), Segment("line", 5.0, 0.0, PUSH)]
    res = check_train(world, TRAIN, (12.0, 0.0, 0.0), segments, margin=margins,
                      field=world.distance_field())
    assert np.isfinite(res.min_clearance) and np.isfinite(res.wall_clearance)
    m = np.broadcast_to(np.asarray(margins, dtype=float), (TRAIN.n + 1,))
    walls = world.free.boundary
    gaps = np.array([[shapely.distance(walls, shapely.polygons(b.corners(
        res.x[k, i], res.y[k, i], res.headings[k, i]))) for i, b in enumerate(TRAIN.bodies)]
        for k in range(res.t.size)])
    assert res.wall_clearance == pytest.approx(gaps.min(), abs=1e-9)
    assert res.min_clearance == pytest.approx((gaps - m[None, :]).min(), abs=1e-9)
    assert (gaps - m[None, :]).min() > 0.0  # all inside: the pruning's case
