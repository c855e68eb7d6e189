"""The closed-loop engine (core/csrc/rollout.c, core/engine.py).

It must run the Python reference loop, tests/reference/closed_loop.py (equal states at the
control instants to 1e-9 on a bay plan and random plans: push, pull, cusps, n = 1, 3, 10; the
core.engine.simulate on it bit for bit), resume bit for bit, stop
exactly where independent computations (shapely for footprints and rectangles, scipy for the
bilinear grid, the joint angles from the states) say a check fails, and agree with the FMU's
kinematic motion along a path to 1 mm.
"""

from __future__ import annotations

import ctypes
import math

import numpy as np
import pytest
import shapely
from reference.closed_loop import simulate_tracking
from scipy.interpolate import RegularGridInterpolator

from pushtrain.core import native
from pushtrain.core.controller import ControllerConfig
from pushtrain.core.engine import Checks, ClosedLoopEngine, LoopState, rectangle_points, simulate
from pushtrain.core.kinematics import ChainGeometry, body_positions, joint_angles, wrap_angle
from pushtrain.core.reference import Reference
from pushtrain.core.segment import PULL, PUSH, Segment
from pushtrain.errors import ControllerError

D = 0.52


def bay_plan():
    """A plan like examples/bay.toml's: pull 4.5 m back along the corridor, cusp, push around
    a 1.7 m arc into the bay and 2.1 m up it."""
    start = (11.5, 1.5, math.pi)
    segments = [Segment("line", 4.5, 0.0, PULL), Segment("arc", 0.5 * math.pi * 1.7, 1 / 1.7, PUSH),
                Segment("line", 2.1, 0.0, PUSH)]
    return start, segments


def random_plan(rng, n_segments: int):
    segments, direction = [], PUSH if rng.random() < 0.6 else PULL
    for _ in range(n_segments):
        if rng.random() < 0.3:
            direction = -direction
        if rng.random() < 0.4:
            segments.append(Segment("line", float(rng.uniform(0.2, 1.2)), 0.0, direction))
        else:
            kappa = float(rng.choice([-1, 1]) * rng.uniform(0.1, 0.8))
            segments.append(Segment("arc", float(rng.uniform(0.2, 1.0)), kappa, direction))
    return segments


def random_geometry(rng, n):
    return ChainGeometry(rng.uniform(0.35, 0.7, n), rng.uniform(0.35, 0.7, n))


def assert_same_run(got, want, tol=1e-9):
    k = want.t.size
    assert got.t.size == k and np.array_equal(got.t, want.t)
    assert np.allclose(got.states, want.state, rtol=0, atol=tol), \
        np.abs(got.states - want.state).max()
    assert np.allclose(got.commands, want.command[:-1], rtol=0, atol=tol)
    assert np.allclose(got.reference, want.reference[:-1], rtol=0, atol=tol)
    assert np.array_equal(got.direction, want.direction[:-1])


def test_equals_simulate_tracking_on_a_bay_plan():
    start, segments = bay_plan()
    geom = ChainGeometry.uniform(3, D)
    ref = Reference.from_segments(start, segments, 0.08, 1.0)
    heads = np.full(4, math.pi)
    config = ControllerConfig(geometry=geom)
    want = simulate_tracking(geom, ref, heads, config, 0.025, 2.0)
    got = simulate(geom, ref, heads, config, 0.025, 2.0)
    assert (want.direction == PULL).any() and (want.direction == 0).any()
    assert_same_run(got, want)
    assert got.violation is None and got.end.k == want.t.size - 1


@pytest.mark.parametrize("n", [1, 3, 10])
def test_equals_simulate_tracking_on_random_plans(n):
    rng = np.random.default_rng(40 + n)
    kinds = set()
    for case in range(4):
        geom = random_geometry(rng, n)
        model = geom if case % 2 == 0 else random_geometry(rng, n)  # the model may differ
        config = ControllerConfig(geometry=model, v_max=0.1, w_max=0.1,
                                  acc_max=None if case == 3 else 0.2,
                                  alpha_max=math.radians(10.0))
        segments = random_plan(rng, 4)
        kinds |= {s.direction for s in segments}
        start = (float(rng.uniform(-2, 2)), float(rng.uniform(-2, 2)), float(rng.uniform(-3, 3)))
        ref = Reference.from_segments(start, segments, float(rng.uniform(0.05, 0.1)),
                                      float(rng.choice([0.0, 1.0])))
        heads = start[2] + np.concatenate((np.cumsum(rng.uniform(-0.2, 0.2, n)[::-1])[::-1],
                                           [0.0]))
        step = float(rng.choice([0.025, 0.05]))
        want = simulate_tracking(geom, ref, heads, config, step, 1.0)
        got = simulate(geom, ref, heads, config, step, 1.0)
        assert_same_run(got, want)
    assert kinds == {PUSH, PULL}


def test_simulate_is_the_reference_loop_bit_for_bit():
    """core.engine.simulate (the planner's check runs it): every row of the reference loop's
    trajectory bit for bit, and a run one instant longer gives the last instant's command,
    reference and direction bit for bit."""
    rng = np.random.default_rng(7)
    start, segments = bay_plan()
    cases = [(ChainGeometry.uniform(3, D), start, segments, np.full(4, math.pi), 0.025, 2.0)]
    for n in (1, 4):
        geom = random_geometry(rng, n)
        cases.append((geom, (0.5, -0.2, 1.0), random_plan(rng, 4), np.full(n + 1, 1.0), 0.05,
                      1.0))
    for geom, first, plan, heads, step, settle in cases:
        ref = Reference.from_segments(first, plan, 0.08, 1.0)
        config = ControllerConfig(geometry=geom)
        want = simulate_tracking(geom, ref, heads, config, step, settle)
        got = simulate(geom, ref, heads, config, step, settle)
        k = want.t.size
        for a, b in ((got.t, want.t), (got.states, want.state),
                     (got.commands, want.command[:-1]), (got.reference, want.reference[:-1]),
                     (got.direction, want.direction[:-1])):
            assert a.shape == b.shape and a.tobytes() == b.tobytes()
        loop = ClosedLoopEngine(geom, config, step)
        longer = loop.run(ref, loop.start(ref.start, heads), k)
        for a, b in ((longer.commands[-1], want.command[-1]),
                     (longer.reference[-1], want.reference[-1])):
            assert a.tobytes() == b.tobytes()
        assert longer.direction[-1] == want.direction[-1]
        # the check samples the reference itself at the run's last instant: the same bits
        last = ref.sample_at(float(got.t[-1]))
        assert np.array([last.x, last.y, last.theta]).tobytes() == want.reference[-1].tobytes()


def test_hold_is_the_reference_rk4_bit_for_bit():
    """ClosedLoopEngine.hold (pt_hold: the loop's own integrator) against the reference's RK4
    step of the towed chain under a held command."""
    from reference.closed_loop import rk4_hold, towed_rates

    rng = np.random.default_rng(8)
    geom = random_geometry(rng, 3)
    loop = ClosedLoopEngine(geom, ControllerConfig(geometry=geom))
    z = [0.3, -0.1, 1.0, 1.1, 0.9, 1.2]
    got = loop.hold(z, -0.08, 0.05, 0.004, 5)
    rates, want = towed_rates(geom), []
    for _ in range(5):
        z = rk4_hold(rates, z, -0.08, 0.05, 0.004)
        want.append(z)
    assert got.tobytes() == np.array(want).tobytes()
    assert loop.hold(z, 0.1, 0.0, 0.01, 0).shape == (0, 6)
    with pytest.raises(ControllerError, match="3 \\+ n"):
        loop.hold(z[:4], 0.1, 0.0, 0.01, 2)


def _bay_loop(checks=None, step=0.025):
    start, segments = bay_plan()
    geom = ChainGeometry.uniform(3, D)
    ref = Reference.from_segments(start, segments, 0.08, 1.0)
    loop = ClosedLoopEngine(geom, ControllerConfig(geometry=geom), step, checks=checks)
    return loop, ref, loop.start(start, np.full(4, math.pi) + [0.05, 0.0, -0.05, 0.0])


def test_resuming_is_bit_identical_to_one_run():
    loop, ref, state = _bay_loop()
    k_end = loop.instant_at(ref.t_end + 2.0)
    whole = loop.run(ref, state, k_end)
    cuts = [0, 1, 2, 350, 351, 1200, k_end - 1, k_end]  # inside the pull, at the cusp, the end
    parts, s = [], state
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        assert s.k == a
        part = loop.run(ref, s, b)
        parts.append(part)
        s = part.end
    assert np.array_equal(np.concatenate([parts[0].states] + [p.states[1:] for p in parts[1:]]),
                          whole.states)
    assert np.array_equal(np.concatenate([p.commands for p in parts]), whole.commands)
    assert s.k == whole.end.k and np.array_equal(s.z, whole.end.z)
    assert (s.v_prev, s.w_prev, s.t_prev) == (whole.end.v_prev, whole.end.w_prev,
                                              whole.end.t_prev)
    # a run without records ends in the same state
    bare = loop.run(ref, state, k_end, record=False)
    assert np.array_equal(bare.end.z, whole.end.z) and bare.states.shape[0] == 0


def test_a_runs_head_continues_as_the_run_went_on():
    """EngineRun.head(k) is the run as it stood at instant k: continued from there (the
    controller's previous command and its time, whose rate limits bind while the robot speeds
    up from rest at k = 1, 2), it gives the rest of the run bit for bit; head(k) of a piece
    that starts later counts its instants from that piece's start; instants outside are
    refused."""
    loop, ref, state = _bay_loop()
    k_end = loop.instant_at(ref.t_end + 2.0)
    whole = loop.run(ref, state, k_end)
    for k in (1, 2, 3, 351, 1200, k_end - 1, k_end):
        head = whole.head(k)
        assert head.end.k == k and head.t.shape[0] == head.states.shape[0] == k + 1
        assert (head.end.v_prev, head.end.w_prev) == tuple(whole.commands[k - 1])
        rest = loop.run(ref, head.end, k_end)
        assert np.array_equal(np.vstack([head.states, rest.states[1:]]), whole.states)
        assert np.array_equal(np.vstack([head.commands, rest.commands]), whole.commands)
        assert (rest.end.v_prev, rest.end.w_prev, rest.end.t_prev) == (
            whole.end.v_prev, whole.end.w_prev, whole.end.t_prev)
    later = loop.run(ref, whole.head(500).end, k_end)
    assert np.array_equal(later.head(700).states, whole.states[500:701])
    for k in (0, k_end + 1):
        with pytest.raises(ControllerError, match="head"):
            whole.head(k)
    with pytest.raises(ControllerError, match="head"):
        later.head(500)


def test_planner_edges_continue_the_reference_and_the_state_bit_for_bit():
    """Edges of one segment each (continuation references; the pull is one edge) give the run
    of the whole reference, and extending a copy does too."""
    start = (0.0, 0.0, math.pi)
    segments = [Segment("line", 0.8), Segment("arc", 0.6, 0.7), Segment("line", 0.4),
                Segment("line", 1.5, 0.0, PULL), Segment("arc", 0.7, -0.5, PUSH)]
    geom = ChainGeometry(np.array([0.5, 0.6, 0.45]), np.array([0.3, 0.52, 0.7]))
    loop = ClosedLoopEngine(geom, ControllerConfig(geometry=geom), 0.025)
    whole_ref = Reference(start, segments, 0.08, 1.0)
    state0 = loop.start(start, np.full(4, math.pi))
    k_end = loop.instant_at(whole_ref.t_end + 2.0)
    whole = loop.run(whole_ref, state0, k_end)

    edge, state, grown = (Reference(start, (), 0.08, 1.0), state0,
                          Reference(start, (), 0.08, 1.0))
    states = [state0.z[None, :]]
    grown_states = [state0.z[None, :]]
    grown_state = state0
    for i, seg in enumerate(segments):
        edge = edge.continuation([seg]) if i else Reference(start, [seg], 0.08, 1.0)
        last = i == len(segments) - 1
        k1 = k_end if last else loop.instant_at(edge.t_end)
        run = loop.run(edge, state, k1)
        states.append(run.states[1:])
        state = run.end
        grown = grown.copy()
        grown.append(seg)
        run = loop.run(grown, grown_state, k1)
        grown_states.append(run.states[1:])
        grown_state = run.end
    assert np.array_equal(np.concatenate(states), whole.states)
    assert np.array_equal(np.concatenate(grown_states), whole.states)


# ---------------------------------------------------------------------- checks


def test_signed_distance_grid_is_bilinear():
    rng = np.random.default_rng(8)
    ny, nx, h, x0, y0 = 7, 11, 0.1, -0.3, 0.2
    grid = rng.normal(size=(ny, nx))
    checks = Checks(1, grid, (x0, y0), h, [np.zeros((1, 2))] * 2)
    interp = RegularGridInterpolator((y0 + h * np.arange(ny), x0 + h * np.arange(nx)), grid)
    pts = np.column_stack([rng.uniform(x0, x0 + h * (nx - 1), 500),
                           rng.uniform(y0, y0 + h * (ny - 1), 500)])
    pts = np.vstack([pts, [[x0, y0], [x0 + h * (nx - 1), y0 + h * (ny - 1)],
                           [x0 + h * (nx - 1), y0], [x0 + 0.25, y0 + h * (ny - 1)]]])
    for x, y in pts:
        assert checks.sdf_at(x, y) == pytest.approx(float(interp([[y, x]])[0]), abs=1e-12)
    for x, y in [(x0 - 1e-9, y0), (x0, y0 - 1e-9), (x0 + h * nx, y0 + 0.1), (math.nan, y0),
                 (x0 + h * (nx - 1) + 1e-9, y0)]:
        assert checks.sdf_at(x, y) == -math.inf
    # exact on a linear field
    yy, xx = np.mgrid[0:ny, 0:nx]
    lin = Checks(1, 0.3 + 2.0 * (x0 + h * xx) - 1.5 * (y0 + h * yy), (x0, y0), h,
                 [np.zeros((1, 2))] * 2)
    for x, y in pts:
        assert lin.sdf_at(x, y) == pytest.approx(0.3 + 2.0 * x - 1.5 * y, abs=1e-12)


def _signed_distance(free, xs, ys):
    """Exact signed distance [m] of points to the blocked space (shapely): + inside ``free``."""
    points = shapely.points(xs, ys)
    d = shapely.distance(free.boundary, points)
    return np.where(shapely.contains(free, points) | shapely.touches(free, points), d, -d)


def _corridor_checks(n, margin, spacing=0.05, h=0.025, phi_max=None):
    # open around the bay plan, but its top wall (y = 4.2) is below the plan's goal (y = 5.3):
    # the last trailer runs into it near the end of the push; a block right of the bay
    free = shapely.box(-1.0, -1.4, 16.0, 4.2).difference(shapely.box(9.4, 2.0, 10.4, 4.2))
    xs = np.arange(3.5, 14.0 + h / 2, h)  # the grid covers the motion; beyond it nothing is free
    ys = np.arange(-1.0, 4.5 + h / 2, h)
    gx, gy = np.meshgrid(xs, ys)
    sdf = _signed_distance(free, gx.ravel(), gy.ravel()).reshape(gx.shape)
    robot = rectangle_points(0.6, 0.5, 0.0, spacing)
    trailer = rectangle_points(0.8, 0.6, 0.0, spacing)
    checks = Checks(n, sdf, (xs[0], ys[0]), h, [robot] + [trailer] * n, margin, phi_max)
    return free, checks, [robot] + [trailer] * n


def test_footprint_check_stops_where_shapely_says_and_not_before():
    free, checks, points = _corridor_checks(3, margin=0.05)
    loop, ref, state = _bay_loop(checks)
    k_end = loop.instant_at(ref.t_end + 2.0)
    run = loop.run(ref, state, k_end)
    v = run.violation
    assert v is not None and v.reason == "footprint"
    h = 0.025
    interp_err = h  # bilinear interpolation of a 1-Lipschitz field errs by less than h
    # the reported point really is (about) closer than the margin
    assert _signed_distance(free, [v.x], [v.y])[0] < 0.05 + interp_err
    assert checks.sdf_at(v.x, v.y) == pytest.approx(v.value) and v.value < 0.05
    geom = loop.plant

    def exact_min(z):
        bx, by = body_positions(z[0], z[1], z[2:], geom)
        out = []
        for b, pts in enumerate(points):
            c, s = math.cos(z[2 + b]), math.sin(z[2 + b])
            wx = bx[b] + c * pts[:, 0] - s * pts[:, 1]
            wy = by[b] + s * pts[:, 0] + c * pts[:, 1]
            out.append(_signed_distance(free, wx, wy).min())
        return np.array(out)

    # before the stop every body's points keep the margin (up to the interpolation error) ...
    assert all((exact_min(z) >= 0.05 - interp_err).all() for z in run.states[:-1][::10])
    assert (exact_min(run.states[-2]) >= 0.05 - interp_err).all()
    # ... and at the stop the reported body does not
    assert exact_min(run.states[-1])[v.body] < 0.05 + interp_err
    # the unchecked run passes the same states: the checks do not change the motion
    plain = ClosedLoopEngine(loop.plant, loop.controller, loop.step).run(ref, state, k_end)
    assert np.array_equal(plain.states[: run.states.shape[0]], run.states)
    # with the block gone (a wider map) nothing fires
    wide = Checks(3, np.full((50, 50), 10.0), (-5.0, -5.0), 1.0, points, 0.05)
    clear = ClosedLoopEngine(loop.plant, loop.controller, loop.step, checks=wide).run(
        ref, state, k_end)
    assert clear.violation is None and clear.end.k == k_end


def test_a_second_tier_of_points_decides_only_for_bodies_that_fail_the_first():
    """Checks(points, margins, fine_points, fine_margins): a body passes a state if all its
    first-tier points keep their margin, or else all its second-tier points keep theirs."""
    free, fine_only, points = _corridor_checks(3, margin=0.05)
    loop, ref, state = _bay_loop(fine_only)
    k_end = loop.instant_at(ref.t_end + 2.0)
    want = loop.run(ref, state, k_end)
    assert want.violation is not None and want.violation.reason == "footprint"
    grid = {"sdf": np.asarray(fine_only._keep[0]), "origin": (fine_only.struct.x0,
            fine_only.struct.y0), "resolution": fine_only.struct.h}
    centre = [np.zeros((1, 2))] * 4

    def run_with(first_margin, k_stop=k_end):
        checks = Checks(3, points=centre, margins=first_margin, fine_points=points,
                        fine_margins=0.05, **grid)
        return ClosedLoopEngine(loop.plant, loop.controller, loop.step, checks=checks).run(
            ref, state, k_stop)

    # a first tier nobody passes: the second decides everywhere, as if alone
    every = run_with(100.0)
    assert every.end.k == want.end.k and np.array_equal(every.states, want.states)
    assert (every.violation.body, every.violation.x, every.violation.y) == (
        want.violation.body, want.violation.x, want.violation.y)
    # a first tier everybody passes (on the grid): the second is never asked
    past = run_with(-100.0, want.end.k + 40)
    assert past.violation is None and past.end.k == want.end.k + 40
    # body centres that must keep 0.3 m: at the stop, the body failing has its centre closer
    # than 0.3 m and a perimeter point closer than 0.05 m; before it, every body has one or
    # the other (checked here with the grid's own interpolation, outside the loop)
    mixed = run_with(0.3)
    v = mixed.violation
    assert v is not None and v.reason == "footprint" and mixed.end.k >= want.end.k

    def tiers(z):
        bx, by = body_positions(z[0], z[1], z[2:], loop.plant)
        out = []
        for b, pts in enumerate(points):
            c, s = math.cos(z[2 + b]), math.sin(z[2 + b])
            centre_ok = fine_only.sdf_at(bx[b], by[b]) >= 0.3
            perimeter_ok = all(fine_only.sdf_at(bx[b] + c * u - s * w, by[b] + s * u + c * w)
                               >= 0.05 for u, w in pts)
            out.append(centre_ok or perimeter_ok)
        return out

    assert all(all(tiers(z)) for z in mixed.states[:-1][::7])
    assert all(tiers(mixed.states[-2])) and not tiers(mixed.states[-1])[v.body]


def test_joint_limit_check_stops_at_the_first_excess():
    rng = np.random.default_rng(9)
    geom = ChainGeometry.uniform(3, D)
    segs = [Segment("arc", 1.2, 1 / 0.9), Segment("arc", 1.0, -1 / 0.8)]
    ref = Reference.from_segments((0.0, 0.0, 0.0), segs, 0.08, 1.0)
    plain_loop = ClosedLoopEngine(geom, ControllerConfig(geometry=geom), 0.025)
    state = plain_loop.start(ref.start, np.zeros(4) + rng.uniform(-0.01, 0.01, 4) * [1, 1, 1, 0])
    plain = plain_loop.run(ref, state, plain_loop.instant_at(ref.t_end + 1.0))
    phi = np.abs(joint_angles(plain.states[:, 2:]))
    for phi_max in (0.3, 0.5, 0.7):
        over = np.flatnonzero((phi > phi_max).any(axis=1))
        checks = Checks(3, phi_max=phi_max)
        run = ClosedLoopEngine(geom, ControllerConfig(geometry=geom), 0.025, checks=checks).run(
            ref, state, plain.end.k)
        if over.size == 0:
            assert run.violation is None
            continue
        k = int(over[0])
        v = run.violation
        assert v is not None and v.reason == "joint_limit" and v.step == k
        assert v.body == int(np.flatnonzero(phi[k] > phi_max)[0]) + 1
        assert abs(v.value) == pytest.approx(phi[k, v.body - 1], abs=1e-15)
        bx, by = body_positions(plain.states[k, 0], plain.states[k, 1], plain.states[k, 2:], geom)
        assert (v.x, v.y) == pytest.approx((bx[v.body], by[v.body]))
        assert run.end.k == k and np.array_equal(run.end.z, plain.states[k])
    assert phi.max() > 0.3  # at least one limit fired


def _rect_polygon(r):
    cx, cy, th, hl, hw = r
    c, s = math.cos(th), math.sin(th)
    corners = [(cx + a * c - b * s, cy + a * s + b * c)
               for a, b in ((hl, hw), (-hl, hw), (-hl, -hw), (hl, -hw))]
    return shapely.Polygon(corners)


def test_rectangle_overlap_equals_shapely():
    lib = native.load()
    rng = np.random.default_rng(11)
    hits = 0
    a, b = np.zeros(5), np.zeros(5)
    pt = np.zeros(2)
    for _ in range(3000):
        a[:] = [*rng.uniform(-1, 1, 2), rng.uniform(-4, 4), *rng.uniform(0.05, 0.6, 2)]
        b[:] = [*rng.uniform(-1, 1, 2), rng.uniform(-4, 4), *rng.uniform(0.05, 0.6, 2)]
        pa, pb = _rect_polygon(a), _rect_polygon(b)
        area = pa.intersection(pb).area
        if 0.0 < area < 1e-9 or (area == 0.0 and pa.distance(pb) < 1e-9):
            continue  # grazing contacts: either answer is right
        got = lib.pt_rects_overlap(native.dptr(a), native.dptr(b), native.dptr(pt))
        assert bool(got) == (area > 0.0)
        if got:
            hits += 1
            overlap = pa.intersection(pb)
            assert overlap.buffer(1e-9).contains(shapely.Point(*pt)) or (
                pa.buffer(1e-9).contains(shapely.Point(*pt))
                and pb.buffer(1e-9).contains(shapely.Point(*pt)))
    assert 300 < hits < 2700


def test_self_collision_check_equals_shapely_on_random_states():
    rng = np.random.default_rng(12)
    n = 4
    geom = ChainGeometry(rng.uniform(0.3, 0.5, n), rng.uniform(0.3, 0.5, n))
    rects = np.column_stack([rng.uniform(-0.1, 0.1, n + 1), np.zeros(n + 1),
                             rng.uniform(0.3, 0.45, n + 1), rng.uniform(0.2, 0.3, n + 1)])
    checks = Checks(n, rectangles=rects)
    lib = native.load()
    work = np.zeros(lib.pt_rollout_work(n))
    chain_arrays = (np.ascontiguousarray(geom.front), np.ascontiguousarray(geom.rear))
    chain = native.PtChain(n, native.dptr(chain_arrays[0]), native.dptr(chain_arrays[1]))
    seen = {True: 0, False: 0}
    for _ in range(1500):
        z = np.concatenate([rng.uniform(-1, 1, 2), np.cumsum(rng.uniform(-2.8, 2.8, n + 1))])
        bx, by = body_positions(z[0], z[1], z[2:], geom)
        polys = []
        for b in range(n + 1):
            c, s = math.cos(z[2 + b]), math.sin(z[2 + b])
            cx, cy = bx[b] + c * rects[b, 0], by[b] + s * rects[b, 0]
            polys.append(_rect_polygon((cx, cy, z[2 + b], rects[b, 2], rects[b, 3])))
        pairs = [(i, j) for i in range(n + 1) for j in range(i + 2, n + 1)]
        areas = [polys[i].intersection(polys[j]).area for i, j in pairs]
        if any(0.0 < a < 1e-9 for a in areas):
            continue
        first = next(((i, j) for (i, j), a in zip(pairs, areas, strict=True) if a > 0.0), None)
        v = native.PtViolation()
        hit = lib.pt_check_state(ctypes.byref(chain), ctypes.byref(checks.struct),
                                 native.dptr(z), 7, native.dptr(work), ctypes.byref(v))
        assert bool(hit) == (first is not None)
        seen[bool(hit)] += 1
        if hit:
            assert v.reason == 4 and v.step == 7 and (v.body, v.other) == first
            p = shapely.Point(v.x, v.y)
            assert polys[v.body].buffer(1e-9).contains(p)
            assert polys[v.other].buffer(1e-9).contains(p)
    assert min(seen.values()) > 200


def test_non_finite_states_and_refused_commands_stop_a_run():
    geom = ChainGeometry.uniform(2, D)
    loop = ClosedLoopEngine(geom, ControllerConfig(geometry=geom), 0.025)
    ref = Reference.from_segments((0.0, 0.0, 0.0), [Segment("line", 1.0)], 0.08)
    good = loop.start(ref.start, np.zeros(3))
    bad = LoopState(good.k, np.array([0.0, math.nan, 0.0, 0.0, 0.0]), 0.0, 0.0, -0.025)
    run = loop.run(ref, bad, 10)
    assert run.violation.reason == "non_finite" and run.end.k == 0 and run.commands.shape == (0, 2)
    empty = Reference((0.0, 0.0, 0.0))  # no segment: the reference refuses to be sampled
    run = loop.run(empty, good, 10)
    assert run.violation.reason == "control" and run.violation.value == 9 and run.end.k == 0
    with pytest.raises(ControllerError, match="k_end"):
        loop.run(ref, LoopState(5, good.z, 0.0, 0.0, None), 4)


# ---------------------------------------------------------------------- the FMU


def _fmu_plant_values(n: int) -> dict:
    """FMU parameters that make its motion kinematic: rolling (slip_mode 0), the smallest
    velocity lag it allows (1 ms), acceleration limits that never bind, no jackknife stop."""
    return {"robot_tau": 1e-3, "robot_acc_max": 100.0, "robot_alpha_max": 100.0, "slip_mode": 0,
            "max_substep": 5e-4, "phi_max": math.radians(179.0)}


@pytest.mark.slow
def test_integrator_equals_the_fmus_kinematic_motion_to_a_millimetre(fmu3):
    """Along the bay plan at the co-simulation's 5 ms step, the last trailer of the integrator
    and of the FMU agree to 1 mm at every step:

    - the same command sequence (the integrator's) replayed into the FMU while the robot pulls
      (the towed chain is stable; replaying a *push* open loop is not: the FMU's 0.08 mm of
      robot lag grows into centimetres within metres, the jackknife instability the controller
      exists to remove, so pushes are compared in closed loop);
    - the whole plan in closed loop: the co-simulation master with the FMU and the controller
      against the integrator.
    """
    from pushtrain.cosim.fmu_slave import TrailerTrainSlave
    from pushtrain.cosim.master import simulate as cosimulate
    from pushtrain.cosim.plant import InitialState, PlantConfig

    step = 0.005
    loop, ref, state = _bay_loop(step=step)
    run = loop.run(ref, state, loop.instant_at(ref.t_end + 2.0))
    geom = loop.plant
    last = np.array([body_positions(z[0], z[1], z[2:], geom) for z in run.states])[:, :, -1]
    pulling = np.flatnonzero(run.direction == PULL)
    assert run.t[pulling[-1]] > 50.0 and (run.direction == PUSH).sum() * step > 50.0

    # the same commands, open loop, over the pull
    with TrailerTrainSlave(fmu3) as slave:
        start = {"x0_start": float(state.z[0]), "y0_start": float(state.z[1]),
                 **_fmu_plant_values(3)}
        start.update({f"theta_start[{i}]": float(a) for i, a in enumerate(state.z[2:])})
        slave.start(start, 0.0)
        write = slave.real_writer(["v_cmd", "w_cmd"])
        read = slave.real_reader([f"x[{geom.n}]", f"y[{geom.n}]"])
        worst = 0.0
        for j in range(pulling[-1] + 1):
            write(run.commands[j])
            slave.do_step(run.t[j], step)
            worst = max(worst, float(np.hypot(*(read() - last[j + 1]))))
    assert worst < 1e-3, worst

    # the whole plan in closed loop
    plant = PlantConfig(3, **_fmu_plant_values(3))
    initial = InitialState(float(state.z[0]), float(state.z[1]), state.z[2:].copy())
    result = cosimulate(fmu3, ref, loop.controller, plant=plant, initial=initial, step=step,
                        settle_time=2.0, check_goal=False)
    data = result.data
    assert result.status == "completed" and len(data) == run.t.size
    assert np.array_equal(data["t"], run.t)
    gap = np.hypot(data["x3"] - last[:, 0], data["y3"] - last[:, 1])
    assert gap.max() < 1e-3, (gap.max(), run.t[np.argmax(gap)])
    # and the plan was followed: the last trailer ends up the bay
    assert abs(float(wrap_angle(run.states[-1, -1] + 0.5 * math.pi))) < math.radians(5.0)
    assert np.hypot(*(last[-1] - ref.goal[:2])) < 0.05


def test_loop_state_phi_is_wrapped_as_the_joint_check_wraps_it():
    """LoopState.phi (the search's pull rule and straight-chain tests read it) is each
    theta_{i-1} - theta_i wrapped to (-pi, pi], whatever turns the headings made."""
    th = np.array([3.0, -3.0, 0.1 + 4.0 * math.pi, 0.1])
    state = LoopState(0, np.concatenate(([0.0, 0.0], th)))
    want = [math.remainder(a - b, 2.0 * math.pi) for a, b in zip(th[:-1], th[1:], strict=True)]
    assert state.phi == pytest.approx(want, abs=1e-12)
    assert np.all(np.abs(state.phi) <= math.pi)
