"""The robot's pulling reference (PullGuide): checked against the forward (towing) kinematics
integrated independently with scipy, against hand-computed run times, and in closed loop."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.engine import simulate
from pushtrain.core.kinematics import (
    ChainGeometry,
    body_positions,
    forward_velocities,
    joint_angles,
)
from pushtrain.core.pulling import PullGuide, straight_chain_mismatch
from pushtrain.core.reference import Reference
from pushtrain.core.sampled_reference import SampledReference
from pushtrain.core.segment import PULL, PUSH, Segment
from pushtrain.errors import ReferencePathError

GEOM = ChainGeometry.uniform(3, 0.52)
CHAIN = float(np.sum(GEOM.front + GEOM.rear))


def _s_curve_pull(start=(0.0, 0.0, 0.3)):
    return Reference.from_segments(
        start,
        [Segment("line", 1.0, 0.0, PULL), Segment("arc", 1.2, 1 / 1.2, PULL),
         Segment("line", 0.5, 0.0, PULL), Segment("arc", 1.5, -1 / 1.5, PULL),
         Segment("line", 2.0, 0.0, PULL)],
        speed=0.08,
    )


def test_straight_pull_leads_a_straight_chain_one_chain_length_ahead():
    ref = Reference.from_segments((1.0, 2.0, 0.4), [Segment("line", 3.0, 0.0, PULL)], speed=0.1)
    guide = PullGuide(ref, GEOM)
    assert len(guide.runs) == 1
    run = guide.runs[0]
    assert run.t[0] == pytest.approx(0.0, abs=1e-9) and run.t[-1] == pytest.approx(30.0, abs=1e-6)
    assert np.allclose(run.headings, 0.4, atol=1e-12)
    for t in (0.0, 7.3, 29.9):
        s = guide.sample_at(t)
        last = ref.sample_at(t)
        assert (s.x - last.x, s.y - last.y) == pytest.approx(
            (CHAIN * math.cos(0.4), CHAIN * math.sin(0.4)), abs=1e-9)
        assert (s.v, s.w, s.direction) == pytest.approx((0.1, 0.0, PULL), abs=1e-9)


def test_towing_the_chain_with_the_guides_robot_reproduces_the_pulled_path():
    """Forward in time, the towed chain (forward map, scipy) driven by the guide's robot
    velocities from the guide's start configuration puts the last trailer on its reference."""
    ref = _s_curve_pull()
    run = PullGuide(ref, GEOM, step=0.01).runs[0]

    def rhs(t, z):
        th = z[2:]
        v0 = np.interp(t, run.t, run.v)
        w0 = np.interp(t, run.t, run.w)
        _, w = forward_velocities(joint_angles(th), v0, w0, GEOM)
        return np.concatenate(([v0 * math.cos(th[0]), v0 * math.sin(th[0])], w))

    z0 = np.concatenate(([run.x[0], run.y[0]], run.headings[0]))
    sol = solve_ivp(rhs, (run.t[0], run.t[-1]), z0, rtol=1e-9, atol=1e-11, max_step=0.05,
                    dense_output=True)
    worst = 0.0
    for t in np.linspace(run.t[0], run.t[-1], 400):
        z = sol.sol(t)
        bx, by = body_positions(z[0], z[1], z[2:], GEOM)
        r = ref.sample_at(min(t, ref.t_end - 1e-9))
        worst = max(worst, math.hypot(bx[-1] - r.x, by[-1] - r.y))
    assert worst < 2e-3
    # the run ends with the chain drawn out straight along the last trailer's heading
    end = ref.sample_at(ref.t_end - 1e-9)
    assert np.allclose(run.headings[-1], end.theta, atol=1e-9)
    # on the arcs the chain bends: the guide is not the straight chain
    assert np.abs(joint_angles(run.headings)).max() > math.radians(20.0)


def test_runs_are_found_between_pushes_and_cusp_dwells():
    ref = Reference.from_segments(
        (0.0, 0.0, math.pi),
        [Segment("line", 1.0, 0.0, PUSH), Segment("line", 0.8, 0.0, PULL),
         Segment("arc", 0.5, 1.0, PUSH), Segment("line", 0.4, 0.0, PULL)],
        speed=0.1, cusp_dwell=2.0,
    )
    guide = PullGuide(ref, GEOM)
    # push 10 s, dwell 2 s, pull 8 s, dwell 2 s, push 5 s, dwell 2 s, pull 4 s
    expected = [(12.0, 20.0), (29.0, 33.0)]
    assert [(r.t[0], r.t[-1]) for r in guide.runs] == [
        pytest.approx(e, abs=1e-6) for e in expected]
    assert guide.sample_at(15.0).direction == PULL
    with pytest.raises(ReferencePathError, match="not in a pulling run"):
        guide.sample_at(5.0)
    # the same runs from the sampled form of the reference
    sampled = SampledReference.from_reference(ref, 0.01)
    runs = PullGuide(sampled, GEOM).runs
    assert [(r.t[0], r.t[-1]) for r in runs] == [pytest.approx(e, abs=0.011) for e in expected]
    with pytest.raises(ReferencePathError, match="step"):
        PullGuide(ref, GEOM, step=0.0)


def test_straight_chain_mismatch_agrees_with_the_guide_and_decays_with_a_lead_in():
    def pulled(lead_in):
        segs = ([Segment("line", lead_in, 0.0, PULL)] if lead_in > 0 else []) + [
            Segment("arc", 1.0, 1 / 1.0, PULL)]
        return Reference.from_segments((0.0, 0.0, 0.0), segs, speed=0.08)

    mismatches = []
    for lead_in in (0.0, 1.0, 2.0, 4.0):
        ref = pulled(lead_in)
        s = np.linspace(0.0, ref.t_end - 1e-9, 2000)
        x, y, th, _, _ = ref.sample(s)
        m = straight_chain_mismatch(GEOM, np.column_stack((x, y, th)))
        # the guide's start configuration, measured the same way (robot position offset)
        run = PullGuide(ref, GEOM, step=0.01).runs[0]
        bx, by = body_positions(0.0, 0.0, run.headings[0], GEOM)
        sx, sy = body_positions(0.0, 0.0, np.zeros(GEOM.n + 1), GEOM)
        offsets = np.hypot((bx - bx[-1]) - (sx - sx[-1]), (by - by[-1]) - (sy - sy[-1]))
        assert m == pytest.approx(offsets.max(), abs=5e-3)
        mismatches.append(m)
    assert mismatches[0] > 0.5  # an arc pulled from a straight chain needs a bent one
    assert all(a > b for a, b in zip(mismatches, mismatches[1:], strict=False))
    assert mismatches[-1] < 0.05
    straight = np.column_stack((np.linspace(0, 2, 50), np.zeros(50), np.zeros(50)))
    assert straight_chain_mismatch(GEOM, straight) == pytest.approx(0.0, abs=1e-12)


def test_closed_loop_pull_from_the_guides_start_tracks_the_s_curve():
    ref = _s_curve_pull()
    guide = PullGuide(ref, GEOM)
    traj = simulate(GEOM, ref, guide.runs[0].headings[0], ControllerConfig(geometry=GEOM),
                    step=0.025, settle_time=0.0)
    th = traj.states[:, 2:]
    err = []
    for k in range(traj.t.size - 1):
        bx, by = body_positions(traj.states[k, 0], traj.states[k, 1], th[k], GEOM)
        err.append(math.hypot(bx[-1] - traj.reference[k, 0], by[-1] - traj.reference[k, 1]))
    assert max(err) < 0.03
    # ... and from a straight chain the S-curve (1.2 m arc right after a 1 m line) cannot be
    # followed: the error is an order of magnitude larger, as straight_chain_mismatch predicts
    traj = simulate(GEOM, ref, np.full(GEOM.n + 1, 0.3), ControllerConfig(geometry=GEOM),
                    step=0.025, settle_time=0.0)
    err_straight = []
    for k in range(traj.t.size - 1):
        bx, by = body_positions(traj.states[k, 0], traj.states[k, 1], traj.states[k, 2:], GEOM)
        err_straight.append(math.hypot(bx[-1] - traj.reference[k, 0],
                                       by[-1] - traj.reference[k, 1]))
    assert max(err_straight) > 10 * max(err)


def test_a_pull_shorter_than_the_integration_step_has_its_run():
    # 0.08 mm of pulling at 0.08 m/s: 1 ms between two pushes, far shorter than the guide's
    # 0.05 s step; a co-simulation sampling every 5 ms may land in it
    ref = Reference.from_segments(
        (0.0, 0.0, math.pi),
        [Segment("line", 0.5, 0.0, PUSH), Segment("arc", 0.00008, 1.0, PULL),
         Segment("line", 0.5, 0.0, PUSH)],
        speed=0.08, cusp_dwell=0.0,
    )
    t_pull = 0.5 / 0.08 + 0.0005
    assert ref.sample_at(t_pull).direction == PULL
    guide = PullGuide(ref, GEOM, step=0.05)
    assert len(guide.runs) == 1
    run = guide.runs[0]
    assert run.t[0] == pytest.approx(0.5 / 0.08, abs=1e-9)
    assert run.t[-1] == pytest.approx(0.5 / 0.08 + 0.001, abs=1e-9)
    s = guide.sample_at(t_pull)
    assert s.direction == PULL and s.v > 0.0
    # the robot stands the chain length ahead of the last trailer, the chain straight
    last = ref.sample_at(t_pull)
    assert math.hypot(s.x - last.x, s.y - last.y) == pytest.approx(CHAIN, abs=1e-3)
    with pytest.raises(ReferencePathError, match="not in a pulling run"):
        guide.sample_at(1.0)
