"""Closed-loop tests of the backward-motion controller on a pure-numpy kinematic plant.

The plant integrates the robot pose and all body headings with RK4 at 5 ms under the robot command
held over the step, using kinematics.forward_velocities (the FMU closed-loop tests live elsewhere).
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from reference.controller import BackwardController, kanayama

from pushtrain.core.analysis import (
    effective_bias,
    steady_lateral_error,
    steady_lateral_error_estimated_pose,
)
from pushtrain.core.controller import (
    MODE_PULL,
    MODE_PUSH,
    MODE_REST,
    ControllerConfig,
    Gains,
)
from pushtrain.core.kinematics import (
    ChainGeometry,
    body_positions,
    forward_velocities,
    inverse_velocities,
    joint_angles,
    wrap_angle,
)
from pushtrain.core.reference import Reference, ReferenceSample
from pushtrain.core.segment import PULL, PUSH, REST, Segment
from pushtrain.core.sensors import Measurement, SensorConfig, Sensors
from pushtrain.errors import ControllerError

H = 0.005
D = 0.52


class KinematicPlant:
    """State (x0, y0, theta_0..theta_n); RK4 with the command held over each step."""

    def __init__(self, geom, x_n, y_n, theta):
        self.geom = geom
        theta = np.asarray(theta, dtype=float)
        x, y = body_positions(x_n, y_n, theta, geom, from_last=True)
        self.state = np.concatenate(([x[0], y[0]], theta))

    def _f(self, s, v0, w0):
        _, w = forward_velocities(joint_angles(s[2:]), v0, w0, self.geom)
        return np.concatenate(([v0 * np.cos(s[2]), v0 * np.sin(s[2])], w))

    def step(self, v0, w0, h=H):
        s = self.state
        k1 = self._f(s, v0, w0)
        k2 = self._f(s + 0.5 * h * k1, v0, w0)
        k3 = self._f(s + 0.5 * h * k2, v0, w0)
        k4 = self._f(s + h * k3, v0, w0)
        self.state = s + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)

    @property
    def theta(self):
        return self.state[2:]

    @property
    def phi(self):
        return joint_angles(self.theta)

    def last_pose(self):
        x, y = body_positions(self.state[0], self.state[1], self.theta, self.geom)
        return x[-1], y[-1], self.theta[-1]

    def measurement(self, sensors=None):
        x0, y0, th0 = self.state[0], self.state[1], self.theta[0]
        if sensors is None:
            return Measurement(x0, y0, th0, self.phi)
        return sensors.measure(x0, y0, th0, self.phi, self.last_pose())


def run_closed_loop(ctrl, reference, plant, t_end, sensors=None, every=20):
    """Simulate; log (t, x_n, y_n, theta_n, v0, w0, phi...) every ``every`` steps."""
    rows = []
    for k in range(int(round(t_end / H))):
        t = k * H
        v0, w0, _info = ctrl.command_from(reference, t, plant.measurement(sensors))
        if k % every == 0:
            rows.append((t, *plant.last_pose(), v0, w0, *plant.phi))
        plant.step(v0, w0)
    rows.append((t_end, *plant.last_pose(), v0, w0, *plant.phi))
    return np.array(rows)


def position_error(log, reference):
    x, y, _, _, _ = reference.sample(log[:, 0])
    return np.hypot(log[:, 1] - x, log[:, 2] - y)


def lateral_error(log, reference):
    """Kanayama y_e of the true last trailer in the reference's direction-of-travel frame."""
    x, y, _th, _, _ = reference.sample(log[:, 0])
    tt = log[:, 3] + np.pi
    return -np.sin(tt) * (x - log[:, 1]) + np.cos(tt) * (y - log[:, 2])


def straight_push(length=8.0, speed=0.08):
    return Reference.from_segments((0.0, 0.0, 0.0), [Segment("line", length)], speed=speed)


# -- the law ------------------------------------------------------------------------------------


def test_kanayama_is_eq3_and_eq4():
    """Eq. 3-4 written out with numpy, and the law's fixed point: no error gives (u_d, w_d)."""
    gains = Gains(1.5, 4.0, 3.0)
    x_e, y_e, th_e, u_d, w_d = 0.12, -0.07, 0.3, 0.08, 0.02
    u, w = kanayama(x_e, y_e, th_e, u_d, w_d, gains)
    assert u == pytest.approx(u_d * np.cos(th_e) + 1.5 * x_e, rel=1e-15)
    assert w == pytest.approx(w_d + u_d * (4.0 * y_e + 3.0 * np.sin(th_e)), rel=1e-15)
    assert kanayama(0.0, 0.0, 0.0, u_d, w_d, gains) == (u_d, w_d)


@pytest.mark.parametrize("direction", [PUSH, PULL])
def test_both_branches_apply_the_one_law(direction):
    """Pushing: the law on trailer n in its travel frame (u_d = -v_d); pulling: on the robot
    along its own reference (u_d = |v_0d|). ControlInfo reports the law's output."""
    cfg = ControllerConfig.uniform(2, k_x=1.5, k_y=3.0, k_theta=2.5, v_max=1e6, w_max=1e6)
    ctrl = BackwardController(cfg)
    meas = Measurement(0.2, -0.1, 0.4, np.array([0.2, -0.1]))
    ref = ReferenceSample(-0.6, 0.3, 0.5, -0.09 * direction, 0.03, direction)  # v < 0 pushing
    leader = ReferenceSample(0.35, 0.0, 0.3, 0.07, -0.02, PULL)
    _, _, info = ctrl.command(0.0, meas, ref, leader if direction == PULL else None)
    assert info.mode == (MODE_PUSH if direction == PUSH else MODE_PULL)
    u_d, w_d = (-ref.v, ref.w) if direction == PUSH else (leader.v, leader.w)
    assert (info.v_ref, info.w_ref) == kanayama(info.x_e, info.y_e, info.theta_e, u_d, w_d,
                                                Gains(1.5, 3.0, 2.5))
    # the errors are the reference in the tracked body's frame (heading + pi when pushing)
    x, y, th = (info.x_n, info.y_n, info.theta_n) if direction == PUSH else (0.2, -0.1, 0.4)
    target = ref if direction == PUSH else leader
    heading = th + (np.pi if direction == PUSH else 0.0)
    dx, dy = target.x - x, target.y - y
    assert info.x_e == pytest.approx(np.cos(heading) * dx + np.sin(heading) * dy, abs=1e-12)
    assert info.y_e == pytest.approx(-np.sin(heading) * dx + np.cos(heading) * dy, abs=1e-12)


# -- pushing ------------------------------------------------------------------------------------


def test_open_loop_pushing_diverges_while_the_closed_loop_holds():
    n = 3
    geom = ChainGeometry.uniform(n, D)
    theta0 = np.radians([1.0, 0.0, 0.0, 0.0])  # 1 deg offset on joint 1
    # open loop: the robot pushes straight back at the reference speed
    plant = KinematicPlant(geom, 0.0, 0.0, theta0)
    for _ in range(int(40.0 / H)):
        plant.step(-0.08, 0.0)
    open_loop = np.max(np.abs(plant.phi))
    # closed loop from the same state
    ref = straight_push(4.0)
    plant = KinematicPlant(geom, 0.0, 0.0, theta0)
    log = run_closed_loop(BackwardController(ControllerConfig(geom)), ref, plant, 40.0)
    assert open_loop > np.radians(30.0)  # jackknifing
    assert np.max(np.abs(log[:, 6:])) < np.radians(5.0)
    assert np.max(np.abs(log[-1, 6:])) < np.radians(1.0)
    assert position_error(log, ref)[-1] < 0.01


def test_straight_reference_from_a_lateral_offset_converges():
    geom = ChainGeometry.uniform(3, D)
    ref = straight_push(6.0)
    plant = KinematicPlant(geom, 0.0, 0.2, np.zeros(4))
    log = run_closed_loop(BackwardController(ControllerConfig(geom)), ref, plant, 60.0)
    err = position_error(log, ref)
    assert err[0] == pytest.approx(0.2)
    assert err[-1] < 0.005
    assert np.all(np.diff(err[log[:, 0] > 30.0]) < 1e-6)  # monotone once settled
    assert np.max(np.abs(log[:, 6:])) < np.radians(60.0)


@pytest.mark.slow
def test_circle_pushed_backward_converges():
    rho, speed, n = 2.5, 0.08, 3
    geom = ChainGeometry.uniform(n, D)
    ref = Reference.from_segments((0.0, 0.0, 0.0), [Segment("arc", 14.0, 1.0 / rho)], speed=speed)
    plant = KinematicPlant(geom, 0.0, 0.2, np.zeros(n + 1))  # straight chain, 0.2 m off
    log = run_closed_loop(BackwardController(ControllerConfig(geom)), ref, plant, 110.0)
    err = position_error(log, ref)
    t = log[:, 0]
    assert np.max(err[t >= 60.0]) < 0.01
    # every joint -> 2 atan(D / rho) = 23.50 deg (sign: the robot turns behind the trailer)
    steady = 2.0 * np.arctan(D / rho)
    np.testing.assert_allclose(np.abs(log[-1, 6:]), steady, atol=np.radians(0.3))
    assert np.all(np.sign(log[-1, 6:]) == -1.0)
    # speed limits hold throughout
    assert np.max(np.abs(log[:, 4])) <= 0.1 + 1e-12 and np.max(np.abs(log[:, 5])) <= 0.1 + 1e-12


def _steady_bias_run(joint, eps, measure_last_pose, n=3, t_end=60.0):
    geom = ChainGeometry.uniform(n, D)
    ref = straight_push(6.0)
    sensors = Sensors(SensorConfig(n, localize="last_trailer" if measure_last_pose else "robot"))
    sensors.set_bias(joint, eps)
    plant = KinematicPlant(geom, 0.0, 0.0, np.zeros(n + 1))
    log = run_closed_loop(BackwardController(ControllerConfig(geom)), ref, plant, t_end, sensors)
    return lateral_error(log, ref)[-1], sensors.bias


@pytest.mark.parametrize("joint, eps_deg", [(3, 5.0), (3, 10.0), (2, 10.0)])
def test_joint_bias_offset_with_a_measured_last_pose(joint, eps_deg):
    """Bias only in the velocity map (paper, Eq. 6-9): y_e = -sin(eps_eff) / (D K_y)."""
    y_e, biases = _steady_bias_run(joint, np.radians(eps_deg), measure_last_pose=True)
    cfg = ControllerConfig.uniform(3)
    predicted = steady_lateral_error(effective_bias(biases), D, cfg.k_y)
    assert y_e == pytest.approx(predicted, rel=0.02)
    last_joint = -np.sin(np.radians(eps_deg)) / (D * cfg.k_y)
    assert np.sign(y_e) == (np.sign(last_joint) if joint == 3 else -np.sign(last_joint))


@pytest.mark.parametrize("joint, eps_deg", [(3, 5.0), (3, 10.0), (2, 10.0)])
@pytest.mark.slow
def test_joint_bias_offset_with_the_pose_estimated_from_the_joints(joint, eps_deg):
    """Bias also in the pose estimate: the exact closed form of the analysis module."""
    y_e, biases = _steady_bias_run(joint, np.radians(eps_deg), measure_last_pose=False)
    cfg = ControllerConfig.uniform(3)
    predicted = steady_lateral_error_estimated_pose(biases, D, cfg.k_x, cfg.k_y, cfg.k_theta, 0.08)
    assert y_e == pytest.approx(predicted, rel=0.02)
    # much larger than the velocity-map-only prediction, and the same sign for joints 2 and 3
    simple = steady_lateral_error(effective_bias(biases), D, cfg.k_y)
    assert abs(y_e) > 2.0 * abs(simple)
    assert y_e < 0.0


# -- pulling and cusps --------------------------------------------------------------------------


def test_pull_segment_is_tracked_stably():
    n = 3
    geom = ChainGeometry.uniform(n, D)
    ref = Reference.from_segments(
        (0.0, 0.0, 0.0),
        [
            Segment("line", 2.0, direction=PULL),
            Segment("arc", 3.0, 0.4, direction=PULL),
            Segment("line", 2.0, direction=PULL),
        ],
        speed=0.08,
    )
    plant = KinematicPlant(geom, 0.0, 0.1, np.zeros(n + 1))
    ctrl = BackwardController(ControllerConfig(geom))
    v, _w, info = ctrl.command_from(ref, 0.0, plant.measurement())
    assert info.mode == MODE_PULL and v > 0.0
    log = run_closed_loop(ctrl, ref, plant, ref.t_end)
    err = position_error(log, ref)
    assert np.max(np.abs(log[:, 6:])) < np.radians(50.0)  # no jackknifing
    assert np.max(err) < 0.35  # transient off-tracking while the robot leads
    assert err[-1] < 0.01  # on the path at the end
    assert np.all(log[:, 4] >= 0.0)  # the robot only pulls


def test_pull_by_steering_the_last_trailer_jackknifes():
    """The rejected scheme: Kanayama on trailer n in its forward frame + inverse map, pulling."""
    n = 3
    geom = ChainGeometry.uniform(n, D)
    plant = KinematicPlant(geom, 0.0, 0.0, np.radians([1.0, 0.0, 0.0, 0.0]))
    u = 0.08
    worst_tracking = 0.0
    for k in range(int(40.0 / H)):
        xn, yn, thn = plant.last_pose()
        dx, dy = u * k * H - xn, -yn
        x_e = np.cos(thn) * dx + np.sin(thn) * dy
        y_e = -np.sin(thn) * dx + np.cos(thn) * dy
        th_e = wrap_angle(-thn)
        v_ref = u * np.cos(th_e) + x_e
        w_ref = u * (4.0 * y_e + 4.0 * np.sin(th_e))
        v, w = inverse_velocities(plant.phi, v_ref, w_ref, geom)
        plant.step(v[0], w[0])
        worst_tracking = max(worst_tracking, np.hypot(dx, dy))
    assert worst_tracking < 1e-3  # the last trailer itself tracks perfectly ...
    assert np.max(np.abs(plant.phi)) > np.radians(90.0)  # ... while the chain jackknifes


@pytest.mark.slow
def test_push_cusp_pull_cusp_push_sequence():
    n = 3
    geom = ChainGeometry.uniform(n, D)
    ref = Reference.from_segments(
        (0.0, 0.0, 0.0),
        [Segment("line", 3.0), Segment("line", 3.0, direction=PULL), Segment("arc", 2.0, 0.3)],
        speed=0.08,
        cusp_dwell=1.0,
    )
    plant = KinematicPlant(geom, 0.0, 0.05, np.zeros(n + 1))
    ctrl = BackwardController(ControllerConfig(geom, acc_max=0.2, alpha_max=0.5))
    modes = {}
    for k in range(int(round((ref.t_end + 5.0) / H))):
        t = k * H
        v0, w0, info = ctrl.command_from(ref, t, plant.measurement())
        modes.setdefault(info.mode, []).append((t, v0, w0))
        plant.step(v0, w0)
        assert np.isfinite(v0) and np.isfinite(w0)
    assert set(modes) == {MODE_PUSH, MODE_PULL, MODE_REST}
    rest = np.array(modes[MODE_REST])
    # at rest the command ramps to zero within the rate limits, then stays zero
    assert np.all(np.abs(rest[:, 1]) <= 0.08 + 1e-12)
    assert rest[-1, 1] == 0.0 and rest[-1, 2] == 0.0
    x_goal, y_goal, _ = ref.goal
    xn, yn, _ = plant.last_pose()
    assert np.hypot(xn - x_goal, yn - y_goal) < 0.05
    assert np.max(np.abs(plant.phi)) < np.radians(40.0)


def test_rest_and_missing_pull_reference():
    ctrl = BackwardController(ControllerConfig.uniform(2))
    meas = Measurement(0.0, 0.0, 0.0, np.array([0.3, -0.2]))
    v, w, info = ctrl.command(0.0, meas, ReferenceSample(-1.0, 0.5, 0.2, 0.0, 0.0, REST))
    assert (v, w, info.mode) == (0.0, 0.0, MODE_REST)
    v, w, info = ctrl.command(0.0, meas, ReferenceSample(-1.0, 0.5, 0.2, 0.0, 0.3, PUSH))
    assert (v, w, info.mode) == (0.0, 0.0, MODE_REST)  # v_d = 0: no division, no motion
    with pytest.raises(ControllerError, match="leader"):
        ctrl.command(0.0, meas, ReferenceSample(1.0, 0.0, 0.0, 0.1, 0.0, PULL))
    with pytest.raises(ControllerError, match="direction"):
        ctrl.command(0.0, meas, ReferenceSample(1.0, 0.0, 0.0, 0.1, 0.0, 2))
    with pytest.raises(ControllerError, match="joint angles"):
        ctrl.command(
            0.0,
            Measurement(0.0, 0.0, 0.0, np.zeros(3)),
            ReferenceSample(1.0, 0.0, 0.0, -0.1, 0.0, PUSH),
        )


# -- limits, model, validation --------------------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(
    phi=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
    xd=st.floats(-3.0, 3.0),
    yd=st.floats(-3.0, 3.0),
    thd=st.floats(-3.0, 3.0),
)
def test_limits_keep_the_curvature(phi, xd, yd, thd):
    geom = ChainGeometry.uniform(3, D)
    free = BackwardController(ControllerConfig(geom, v_max=1e6, w_max=1e6))
    limited = BackwardController(ControllerConfig(geom))
    meas = Measurement(0.1, -0.2, 0.3, np.array(phi))
    ref = ReferenceSample(xd, yd, thd, -0.1, 0.02, PUSH)
    v_raw, w_raw, _ = free.command(0.0, meas, ref)
    v, w, info = limited.command(0.0, meas, ref)
    assert abs(v) <= 0.1 + 1e-12 and abs(w) <= 0.1 + 1e-12
    assert (info.v_raw, info.w_raw) == pytest.approx((v_raw, w_raw))
    # common scaling: (v, w) is parallel to (v_raw, w_raw), same direction
    assert v * w_raw - w * v_raw == pytest.approx(0.0, abs=1e-12)
    assert v * v_raw + w * w_raw >= 0.0
    assert (v, w) == pytest.approx((v_raw / info.scale, w_raw / info.scale))
    assert max(abs(v) / 0.1, abs(w) / 0.1) == pytest.approx(1.0) or info.scale == 1.0


def test_rate_limits():
    ctrl = BackwardController(ControllerConfig.uniform(1, acc_max=0.1, alpha_max=0.2))
    meas = Measurement(0.0, 0.0, 0.0, np.array([0.0]))
    ref = ReferenceSample(-5.0, 1.0, 0.0, -0.1, 0.0, PUSH)  # far away: saturated command
    v, w, _ = ctrl.command(0.0, meas, ref)  # without a known previous time: not rate limited
    assert max(abs(v), abs(w)) == pytest.approx(0.1)
    ctrl.reset(0.0, 0.0, t=0.0)  # starting from rest at t = 0
    prev = (0.0, 0.0)
    for k in range(1, 400):
        v, w, _ = ctrl.command(k * H, meas, ref)
        assert abs(v - prev[0]) <= 0.1 * H + 1e-12 and abs(w - prev[1]) <= 0.2 * H + 1e-12
        prev = (v, w)
    assert max(abs(prev[0]), abs(prev[1])) == pytest.approx(0.1)  # reaches the limit


@settings(max_examples=50, deadline=None)
@given(n=st.integers(1, 6), data=st.data())
def test_fast_kinematics_equal_the_kinematics_module(n, data):
    floats = st.floats(0.2, 1.0)
    geom = ChainGeometry(
        data.draw(st.lists(floats, min_size=n, max_size=n)),
        data.draw(st.lists(floats, min_size=n, max_size=n)),
    )
    phi = np.array(data.draw(st.lists(st.floats(-1.2, 1.2), min_size=n, max_size=n)))
    th0, v, w = (
        data.draw(st.floats(-3, 3)),
        data.draw(st.floats(-1, 1)),
        data.draw(st.floats(-1, 1)),
    )
    ctrl = BackwardController(ControllerConfig(geom))
    theta = th0 - np.concatenate(([0.0], np.cumsum(phi)))
    x, y = body_positions(0.3, -0.4, theta, geom)
    assert ctrl.last_trailer_pose(0.3, -0.4, th0, phi) == pytest.approx((x[-1], y[-1], theta[-1]))
    vi, wi = inverse_velocities(phi, v, w, geom)
    assert ctrl.robot_velocity(phi, v, w) == pytest.approx((vi[0], wi[0]), abs=1e-12)


def test_model_mismatch_still_converges():
    """The controller's own geometry differs from the plant's by 5 %."""
    plant_geom = ChainGeometry([0.52, 0.50, 0.55], [0.52, 0.54, 0.50])
    ref = straight_push(5.0)
    plant = KinematicPlant(plant_geom, 0.0, 0.15, np.zeros(4))
    ctrl = BackwardController(ControllerConfig.uniform(3, 0.52))
    log = run_closed_loop(ctrl, ref, plant, 50.0)
    assert abs(lateral_error(log, ref)[-1]) < 0.01
    assert np.max(np.abs(log[-1, 6:])) < np.radians(2.0)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(k_x=0.0), "k_x"),
        (dict(k_y=-1.0), "k_y"),
        (dict(k_theta=np.nan), "k_theta"),
        (dict(v_max=0.0), "v_max"),
        (dict(w_max=-0.1), "w_max"),
        (dict(acc_max=0.0), "acc_max"),
        (dict(alpha_max=np.inf), "alpha_max"),
        (dict(rest_speed=-1.0), "rest_speed"),
    ],
)
def test_bad_config_raises(kwargs, field):
    with pytest.raises(ControllerError, match=field):
        ControllerConfig.uniform(3, **kwargs)
    assert issubclass(ControllerError, ValueError)


def test_bad_geometry_and_config_types_raise():
    with pytest.raises(ControllerError, match="geometry"):
        ControllerConfig(geometry=[0.52, 0.52])
    with pytest.raises(ControllerError, match="n_trailers"):
        ControllerConfig.uniform(0)
    with pytest.raises(ControllerError, match="config"):
        BackwardController({"k_x": 1.0})
