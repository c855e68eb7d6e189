"""Chain kinematics of the TrailerTrain FMU against independent computations.

References: ``pushtrain.core.kinematics`` (numpy, written apart from the C code), the paper's
Eq. (5), closed-form steady circles, finite differences of the FMU's own positions, and a
scipy integration of the model's ODE written here.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pushtrain.core.kinematics import (
    ChainGeometry,
    body_positions,
    eq5_matrix,
    forward_velocities,
    joint_angles,
)

ROBOT_TAU = 0.05  # the FMU's default robot_tau [s]
ACC_MAX = 1.0  # default robot_acc_max [m/s^2]
ALPHA_MAX = 2.0  # default robot_alpha_max [rad/s^2]


def link_params(geom: ChainGeometry) -> dict:
    """FMU parameters front[i] = F_i (i = 1..n), rear[k] = R_k (k = 0..n-1)."""
    params = {f"front[{i}]": float(geom.front[i - 1]) for i in range(1, geom.n + 1)}
    params.update({f"rear[{k}]": float(geom.rear[k]) for k in range(geom.n)})
    return params


def heading_params(theta) -> dict:
    return {f"theta_start[{i}]": float(t) for i, t in enumerate(theta)}


def random_chain(rng, n, equal_links=False):
    if equal_links:
        geom = ChainGeometry.uniform(n, float(rng.uniform(0.3, 0.9)))
    else:
        geom = ChainGeometry(rng.uniform(0.25, 0.9, n), rng.uniform(0.25, 0.9, n))
    phi = rng.uniform(-1.2, 1.2, n)
    theta0 = rng.uniform(-np.pi, np.pi)
    theta = theta0 - np.concatenate(([0.0], np.cumsum(phi)))
    return geom, theta


# -- velocity maps at random configurations ------------------------------------------------------
@pytest.mark.parametrize("n_trailers", [1, 2, 3, 4, 5])
def test_velocities_and_positions_after_init_match_kinematics(built_fmu_sim, n_trailers):
    rng = np.random.default_rng(100 + n_trailers)
    for trial in range(4):
        geom, theta = random_chain(rng, n_trailers)
        v0, w0 = rng.uniform(-0.5, 0.5), rng.uniform(-0.6, 0.6)
        x0, y0 = rng.uniform(-3, 3, 2)
        sim = built_fmu_sim(n_trailers, instance_name=f"t{trial}")
        params = {**link_params(geom), **heading_params(theta), "v_start": v0, "w_start": w0,
                  "x0_start": x0, "y0_start": y0}
        sim.initialize(params, {"v_cmd": v0, "w_cmd": w0})
        v_ref, w_ref = forward_velocities(joint_angles(theta), v0, w0, geom)
        x_ref, y_ref = body_positions(x0, y0, theta, geom)
        np.testing.assert_allclose(sim.array("v"), v_ref, rtol=0, atol=1e-12)
        np.testing.assert_allclose(sim.array("w"), w_ref, rtol=0, atol=1e-12)
        np.testing.assert_allclose(sim.array("x"), x_ref, rtol=0, atol=1e-12)
        np.testing.assert_allclose(sim.array("y"), y_ref, rtol=0, atol=1e-12)
        np.testing.assert_allclose(sim.array("theta"), theta, rtol=0, atol=1e-15)
        np.testing.assert_allclose(sim.array("phi"), joint_angles(theta), rtol=0, atol=1e-12)
        sim.free()


@pytest.mark.parametrize("n_trailers", [1, 2, 3, 4, 5])
def test_last_trailer_velocities_invert_through_paper_eq5(built_fmu_sim, n_trailers):
    """For D = F = R the paper's Eq. (5) maps the FMU's (v_n, w_n) back to the robot's (v0, w0)."""
    rng = np.random.default_rng(200 + n_trailers)
    for trial in range(4):
        geom, theta = random_chain(rng, n_trailers, equal_links=True)
        v0, w0 = rng.uniform(-0.5, 0.5), rng.uniform(-0.6, 0.6)
        sim = built_fmu_sim(n_trailers, instance_name=f"t{trial}")
        sim.initialize({**link_params(geom), **heading_params(theta), "v_start": v0,
                        "w_start": w0})
        v, w = sim.array("v"), sim.array("w")
        robot = eq5_matrix(theta, float(geom.front[0])) @ np.array([v[-1], w[-1]])
        np.testing.assert_allclose(robot, [v0, w0], rtol=0, atol=1e-12)
        sim.free()


# -- steady circles ------------------------------------------------------------------------------
def steady_circle(rho0, geom):
    """Radii rho_i and joint angles on a steady CCW circle (robot on radius rho0) [m, rad]."""
    rho = [rho0]
    phi = []
    for i in range(1, geom.n + 1):
        f, r = geom.front[i - 1], geom.rear[i - 1]
        rho.append(np.sqrt(rho[-1] ** 2 + r**2 - f**2))
        # hitch point seen from the centre: atan(R/rho_{i-1}) behind body i-1, atan(F/rho_i)
        # ahead of body i
        phi.append(np.arctan(r / rho[i - 1]) + np.arctan(f / rho[i]))
    return np.array(rho), np.array(phi)


@pytest.mark.parametrize(
    "n_trailers, front, rear",
    [(3, 0.52, 0.52), (5, 0.52, 0.52), (3, 0.4, 0.6), (2, 0.6, 0.4)],
)
def test_towing_on_a_circle_settles_on_the_predicted_radii(built_fmu_sim, n_trailers, front,
                                                           rear):
    rho0, speed = 2.5, 0.1
    geom = ChainGeometry(np.full(n_trailers, front), np.full(n_trailers, rear))
    sim = built_fmu_sim(n_trailers)
    # the robot starts on its circle (v, w already at the command), the chain straight behind
    sim.initialize({**link_params(geom), "v_start": speed, "w_start": speed / rho0},
                   {"v_cmd": speed, "w_cmd": speed / rho0})
    centre = np.array([0.0, rho0])  # robot at the origin heading +x, turning left
    rho_ref, phi_ref = steady_circle(rho0, geom)
    if front == rear:
        assert phi_ref == pytest.approx(np.full(n_trailers, 2 * np.arctan(0.52 / rho0)))
        assert rho_ref == pytest.approx(np.full(n_trailers + 1, rho0))
    h = 0.05
    for k in range(1, 12001):  # 600 s
        sim.step(h)
        if k % 2000 == 0:
            radius_robot = np.hypot(sim.real("x[0]") - centre[0], sim.real("y[0]") - centre[1])
            assert radius_robot == pytest.approx(rho0, abs=1e-9)
    for _ in range(5):  # the last 25 s: settled
        for _ in range(100):
            sim.step(h)
        radii = np.hypot(sim.array("x") - centre[0], sim.array("y") - centre[1])
        np.testing.assert_allclose(radii, rho_ref, rtol=0, atol=1e-6)
        np.testing.assert_allclose(sim.array("phi"), phi_ref, rtol=0, atol=1e-7)


# -- no lateral slip along a smooth trajectory ---------------------------------------------------
def smooth_inputs(t, a):
    """A smooth random-looking robot command (v_cmd [m/s], w_cmd [rad/s]) at time t."""
    v = 0.25 * np.sin(0.9 * t + a[0]) + 0.1 * np.sin(2.3 * t + a[1])
    w = 0.35 * np.sin(0.7 * t + a[2]) + 0.15 * np.cos(1.9 * t + a[3])
    return {"v_cmd": v, "w_cmd": w}


@pytest.mark.parametrize("n_trailers, slide", [(3, None), (5, None), (3, (0.0, 0.03, -0.02))])
def test_axle_velocity_has_no_lateral_component(built_fmu_sim, n_trailers, slide):
    """Central differences of x[i], y[i]: lateral speed 0 (or the imposed slide[i]).

    The step h = 1e-4 s keeps the difference error h^2/6 |d3P/dt3| below 1e-8 m/s here, and the
    inputs are held constant across each difference window.
    """
    rng = np.random.default_rng(300 + n_trailers)
    geom, theta = random_chain(rng, n_trailers)
    theta = theta[0] - 0.5 * (theta[0] - theta)  # milder joint angles
    a = rng.uniform(0, 2 * np.pi, 4)
    sim = built_fmu_sim(n_trailers)
    inputs = smooth_inputs(0.0, a)
    if slide is not None:
        inputs.update({f"slide[{i}]": u for i, u in enumerate(slide, start=1)})
    sim.initialize({**link_params(geom), **heading_params(theta)}, inputs)
    u = np.zeros(n_trailers + 1) if slide is None else np.concatenate(([0.0], slide))
    coarse, fine = 0.01, 1e-4
    checked = 0
    worst = 0.0
    for k in range(1, 1201):  # 12 s of coarse steps, a difference window every 0.4 s
        sim.set(smooth_inputs(sim.time, a))
        sim.step(coarse)
        if k % 40:
            continue
        sim.set(smooth_inputs(sim.time, a))
        p_before = np.array([sim.array("x"), sim.array("y")])
        sim.step(fine)
        theta_mid = sim.array("theta")
        v_mid = sim.array("v")
        sim.step(fine)
        p_after = np.array([sim.array("x"), sim.array("y")])
        vel = (p_after - p_before) / (2 * fine)
        lateral = -np.sin(theta_mid) * vel[0] + np.cos(theta_mid) * vel[1]
        longitudinal = np.cos(theta_mid) * vel[0] + np.sin(theta_mid) * vel[1]
        np.testing.assert_allclose(lateral, u, rtol=0, atol=1e-6)
        np.testing.assert_allclose(longitudinal, v_mid, rtol=0, atol=1e-6)
        worst = max(worst, float(np.max(np.abs(v_mid))))
        checked += 1
    assert checked == 30
    assert worst > 0.05, "the trajectory must actually move"


# -- integration against scipy -------------------------------------------------------------------
def chain_rhs(theta, v0, w0, front, rear, slide):
    """d(theta_i)/dt of every body for robot speeds (v0, w0) and lateral slides u_1..u_n."""
    n = len(theta) - 1
    w = np.empty(n + 1)
    w[0] = w0
    v_prev, w_prev, u_prev = v0, w0, 0.0
    for i in range(1, n + 1):
        c, s = np.cos(theta[i - 1] - theta[i]), np.sin(theta[i - 1] - theta[i])
        r, f, u = rear[i - 1], front[i - 1], slide[i - 1]
        v_i = c * v_prev + s * (r * w_prev - u_prev)
        w[i] = (s * v_prev + c * (u_prev - r * w_prev) - u) / f
        v_prev, w_prev, u_prev = v_i, w[i], u
    return w


def model_ode(t, state, v_cmd, w_cmd, front, rear, slide, tau, acc_max, alpha_max):
    """State: x0, y0 [m], theta_0..theta_n [rad], v0 [m/s], w0 [rad/s]."""
    n = len(front)
    theta = state[2:n + 3]
    v0, w0 = state[n + 3], state[n + 4]
    out = np.empty_like(state)
    out[0] = v0 * np.cos(theta[0])  # robot moves along its heading
    out[1] = v0 * np.sin(theta[0])
    out[2:n + 3] = chain_rhs(theta, v0, w0, front, rear, slide)
    out[n + 3] = np.clip((v_cmd - v0) / tau, -acc_max, acc_max)  # velocity loop, rate-limited
    out[n + 4] = np.clip((w_cmd - w0) / tau, -alpha_max, alpha_max)
    return out


@pytest.mark.parametrize(
    "n_trailers, clipping, with_slide",
    [(1, False, False), (3, False, False), (5, False, True), (3, True, False)],
)
def test_trajectory_matches_scipy_integration(built_fmu_sim, n_trailers, clipping, with_slide):
    rng = np.random.default_rng(400 + 10 * n_trailers + clipping)
    geom, theta = random_chain(rng, n_trailers)
    theta = theta[0] - 0.4 * (theta[0] - theta)
    x0, y0 = rng.uniform(-1, 1, 2)
    v_start, w_start = -0.1, 0.05
    slide = rng.uniform(-0.02, 0.02, n_trailers) if with_slide else np.zeros(n_trailers)
    tau, acc_max, alpha_max = 0.2, 0.5, 0.8
    params = {**link_params(geom), **heading_params(theta), "x0_start": x0, "y0_start": y0,
              "v_start": v_start, "w_start": w_start, "robot_tau": tau,
              "robot_acc_max": acc_max, "robot_alpha_max": alpha_max}
    if clipping:
        # input jumps beyond the rate limits put kinks into the lag law; small substeps keep
        # RK4 accurate across them
        params["max_substep"] = 2e-4
    sim = built_fmu_sim(n_trailers)
    sim.initialize(params, {"v_cmd": v_start, "w_cmd": w_start,
                            **{f"slide[{i}]": float(u) for i, u in enumerate(slide, 1)}})

    state = np.concatenate(([x0, y0], theta, [v_start, w_start]))
    h, per_segment, segments = 0.1, 5, 8
    v_cmd, w_cmd = v_start, w_start
    clipped = False
    for _seg in range(segments):
        if clipping:
            v_cmd = float(rng.uniform(-0.4, 0.4))
            w_cmd = float(rng.uniform(-0.5, 0.5))
        else:  # steps small enough that |cmd - v| / tau stays below the limits
            v_cmd = float(np.clip(v_cmd + rng.uniform(-0.08, 0.08), -0.4, 0.4))
            w_cmd = float(np.clip(w_cmd + rng.uniform(-0.12, 0.12), -0.5, 0.5))
        # the lag law's demand is largest at the segment start (the error then decays)
        clipped |= (abs(v_cmd - state[-2]) / tau > acc_max
                    or abs(w_cmd - state[-1]) / tau > alpha_max)
        sim.set({"v_cmd": v_cmd, "w_cmd": w_cmd})
        for _ in range(per_segment):
            t0 = sim.time
            sol = solve_ivp(model_ode, (t0, t0 + h), state, method="DOP853", rtol=1e-11,
                            atol=1e-13, args=(v_cmd, w_cmd, geom.front, geom.rear, slide, tau,
                                              acc_max, alpha_max))
            assert sol.success, sol.message
            state = sol.y[:, -1]
            sim.step(h)
            theta_ref = state[2:n_trailers + 3]
            x_ref, y_ref = body_positions(state[0], state[1], theta_ref, geom)
            np.testing.assert_allclose(sim.array("theta"), theta_ref, rtol=0, atol=1e-7)
            np.testing.assert_allclose(sim.array("x"), x_ref, rtol=0, atol=1e-7)
            np.testing.assert_allclose(sim.array("y"), y_ref, rtol=0, atol=1e-7)
            assert sim.real("v[0]") == pytest.approx(state[-2], abs=1e-7)
            assert sim.real("w[0]") == pytest.approx(state[-1], abs=1e-7)
    assert clipped == clipping
