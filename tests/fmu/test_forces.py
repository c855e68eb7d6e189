"""Lateral wheel and hitch forces of the TrailerTrain FMU against an independent global solve.

The reference writes all 3n Newton-Euler equations of the trailers at once
(unknowns f_1..f_n (x, y) and F_d,1..F_d,n) and solves them with one dense linear solve. The
accelerations come from complex-step differentiation of the velocity map along the motion, not
from closed-form acceleration formulas.
"""

from __future__ import annotations

import numpy as np
import pytest

G = 9.81
COMPLEX_STEP = 1e-30


def axle_velocities(theta, v0, w0, front, rear):
    """Axle-midpoint velocity vectors (n+1, 2) and yaw rates (n+1,) of every body.

    Works in complex arithmetic (for the complex step). Rolling wheels: each body's axle moves
    along its heading only; the hitch points of neighbours coincide.
    """
    n = len(theta) - 1
    speed = [v0]
    rate = [w0]
    for i in range(1, n + 1):
        # velocity of the hitch point of body i-1 (at P_{i-1} - R e_{i-1})
        e_prev = np.array([np.cos(theta[i - 1]), np.sin(theta[i - 1])])
        n_prev = np.array([-np.sin(theta[i - 1]), np.cos(theta[i - 1])])
        hitch_vel = speed[i - 1] * e_prev - rear[i - 1] * rate[i - 1] * n_prev
        e_i = np.array([np.cos(theta[i]), np.sin(theta[i])])
        n_i = np.array([-np.sin(theta[i]), np.cos(theta[i])])
        # trailer i: P_i = H - F e_i, dP_i = v_i e_i (no lateral slip) => project on e_i, n_i
        speed.append(hitch_vel @ e_i)
        rate.append((hitch_vel @ n_i) / front[i - 1])
    speed = np.array(speed)
    rate = np.array(rate)
    heading = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    return speed[:, None] * heading, rate


def accelerations(theta, v0, w0, dv0, dw0, front, rear):
    """Axle accelerations (n+1, 2) and yaw accelerations (n+1,) by complex step along the motion.

    d/dt of (velocity map at the current state) along ds/dt = (dtheta/dt, dv0/dt, dw0/dt).
    """
    _, rate = axle_velocities(theta, v0, w0, front, rear)
    eps = COMPLEX_STEP
    vel_c, rate_c = axle_velocities(theta + 1j * eps * rate, v0 + 1j * eps * dv0,
                                    w0 + 1j * eps * dw0, front, rear)
    return vel_c.imag / eps, rate_c.imag / eps


def global_force_solve(theta, acc, alpha, front, rear, mass, inertia, push):
    """Solve the 3n Newton-Euler equations of trailers 1..n at once.

    Unknowns z = (f_1x, f_1y, ..., f_nx, f_ny, F_d1, ..., F_dn): f_i hitch force of body i-1 on
    trailer i (world frame), F_d,i lateral wheel force along n_i. Equations for trailer i:
    m_i a_i = f_i - f_{i+1} + F_d,i n_i (+ push on trailer n),
    I_i alpha_i = F_i n_i . f_i + R_i n_i . f_{i+1}, with f_{n+1} = 0.
    """
    n = len(theta) - 1
    a_mat = np.zeros((3 * n, 3 * n))
    rhs = np.zeros(3 * n)
    for i in range(1, n + 1):
        row = 3 * (i - 1)
        f_col = 2 * (i - 1)
        fd_col = 2 * n + (i - 1)
        n_i = np.array([-np.sin(theta[i]), np.cos(theta[i])])
        # force balance (x, y)
        a_mat[row, f_col] = 1.0
        a_mat[row + 1, f_col + 1] = 1.0
        a_mat[row:row + 2, fd_col] = n_i
        if i < n:
            a_mat[row, f_col + 2] = -1.0
            a_mat[row + 1, f_col + 3] = -1.0
        rhs[row:row + 2] = mass[i - 1] * acc[i]
        if i == n:
            rhs[row:row + 2] -= push
        # moment balance about the axle midpoint
        a_mat[row + 2, f_col:f_col + 2] = front[i - 1] * n_i
        if i < n:
            a_mat[row + 2, f_col + 2:f_col + 4] = rear[i] * n_i
        rhs[row + 2] = inertia[i - 1] * alpha[i]
    z = np.linalg.solve(a_mat, rhs)
    hitch = z[:2 * n].reshape(n, 2)
    return hitch, z[2 * n:]


def lag(cmd, value, tau, limit):
    return float(np.clip((cmd - value) / tau, -limit, limit))


def test_reference_velocity_map_matches_kinematics_module():
    from pushtrain.core.kinematics import ChainGeometry, forward_velocities, joint_angles

    rng = np.random.default_rng(2)
    n = 4
    front, rear = rng.uniform(0.3, 0.8, n), rng.uniform(0.3, 0.8, n)
    theta = rng.uniform(-2, 2, n + 1)
    vel, rate = axle_velocities(theta, -0.2, 0.3, front, rear)
    speed, yaw = forward_velocities(joint_angles(theta), -0.2, 0.3, ChainGeometry(front, rear))
    np.testing.assert_allclose(rate, yaw, atol=1e-14)
    np.testing.assert_allclose(vel, speed[:, None] * np.stack([np.cos(theta), np.sin(theta)], 1),
                               atol=1e-14)


def test_complex_step_accelerations_match_finite_differences():
    """The reference accelerations agree with a central difference along a short integration."""
    rng = np.random.default_rng(1)
    n = 3
    front, rear = rng.uniform(0.3, 0.8, n), rng.uniform(0.3, 0.8, n)
    theta = np.array([0.3, -0.2, 0.5, 0.1])
    v0, w0, dv0, dw0 = -0.3, 0.4, 0.7, -1.1
    acc, alpha = accelerations(theta, v0, w0, dv0, dw0, front, rear)

    def velocity_at(dt):
        # second-order Taylor of the state along the motion is enough for a central difference
        _, rate = axle_velocities(theta, v0, w0, front, rear)
        th = theta + rate * dt
        return axle_velocities(th, v0 + dv0 * dt, w0 + dw0 * dt, front, rear)

    h = 1e-6
    (vel_p, rate_p), (vel_m, rate_m) = velocity_at(h), velocity_at(-h)
    np.testing.assert_allclose(acc, (vel_p - vel_m) / (2 * h), atol=1e-6)
    np.testing.assert_allclose(alpha, (rate_p - rate_m) / (2 * h), atol=1e-6)


def random_case(rng, n):
    front = rng.uniform(0.3, 0.8, n)
    rear = rng.uniform(0.3, 0.8, n)
    mass = rng.uniform(20.0, 70.0, n)
    payload = rng.uniform(0.0, 40.0, n) * (rng.random(n) < 0.6)
    inertia = rng.uniform(1.0, 6.0, n)
    mu = rng.uniform(0.05, 0.3, n)
    theta = rng.uniform(-np.pi, np.pi) - np.concatenate(([0.0], np.cumsum(rng.uniform(-1, 1, n))))
    v0, w0 = rng.uniform(-0.4, 0.4), rng.uniform(-0.5, 0.5)
    tau = rng.uniform(0.05, 0.4)
    acc_max, alpha_max = rng.uniform(0.5, 2.0), rng.uniform(0.8, 3.0)
    # commands within the rate limits (|cmd - v| / tau below the limit)
    v_cmd = v0 + rng.uniform(-0.9, 0.9) * acc_max * tau
    w_cmd = w0 + rng.uniform(-0.9, 0.9) * alpha_max * tau
    push = rng.uniform(-30.0, 30.0, 2)
    params = {"robot_tau": tau, "robot_acc_max": acc_max, "robot_alpha_max": alpha_max,
              "v_start": v0, "w_start": w0}
    for i in range(1, n + 1):
        params.update({f"front[{i}]": front[i - 1], f"rear[{i - 1}]": rear[i - 1],
                       f"mass[{i}]": mass[i - 1], f"payload[{i}]": payload[i - 1],
                       f"inertia[{i}]": inertia[i - 1], f"mu[{i}]": mu[i - 1]})
    params.update({f"theta_start[{i}]": t for i, t in enumerate(theta)})
    inputs = {"v_cmd": v_cmd, "w_cmd": w_cmd, "push_x": push[0], "push_y": push[1]}
    return params, inputs


def reference_forces(params, inputs, theta, v0, w0, n):
    """Hitch forces (n, 2) and lateral forces (n,) of the global solve for this state/inputs."""
    def arr(name, first=1):
        return np.array([params[f"{name}[{i}]"] for i in range(first, first + n)])

    front, rear, mass = arr("front"), arr("rear", 0), arr("mass") + arr("payload")
    inertia = arr("inertia")
    dv0 = lag(inputs["v_cmd"], v0, params["robot_tau"], params["robot_acc_max"])
    dw0 = lag(inputs["w_cmd"], w0, params["robot_tau"], params["robot_alpha_max"])
    acc, alpha = accelerations(np.asarray(theta, float), v0, w0, dv0, dw0, front, rear)
    push = np.array([inputs["push_x"], inputs["push_y"]])
    return global_force_solve(theta, acc, alpha, front, rear, mass, inertia, push)


def assert_forces_match(sim, params, inputs, n):
    theta = sim.array("theta")
    v0, w0 = sim.real("v[0]"), sim.real("w[0]")
    hitch, lateral = reference_forces(params, inputs, theta, v0, w0, n)
    scale = 1.0 + float(np.max(np.abs(hitch)))
    np.testing.assert_allclose(sim.array("F_lat"), lateral, rtol=1e-9, atol=1e-9 * scale)
    np.testing.assert_allclose(sim.array("hitch_fx"), hitch[:, 0], rtol=1e-9, atol=1e-9 * scale)
    np.testing.assert_allclose(sim.array("hitch_fy"), hitch[:, 1], rtol=1e-9, atol=1e-9 * scale)
    return lateral


@pytest.mark.parametrize("n_trailers", [1, 2, 3, 4, 5])
def test_forces_after_init_match_global_newton_euler_solve(built_fmu_sim, n_trailers):
    rng = np.random.default_rng(500 + n_trailers)
    for trial in range(5):
        params, inputs = random_case(rng, n_trailers)
        sim = built_fmu_sim(n_trailers, instance_name=f"t{trial}")
        sim.initialize(params, inputs)
        lateral = assert_forces_match(sim, params, inputs, n_trailers)
        assert np.max(np.abs(lateral)) > 0.1, "the case must load the wheels"
        sim.free()


@pytest.mark.parametrize("n_trailers", [2, 4])
def test_forces_follow_new_inputs_and_states(built_fmu_sim, n_trailers):
    """Forces are recomputed right after an input is set, and stay right along a run."""
    rng = np.random.default_rng(600 + n_trailers)
    params, inputs = random_case(rng, n_trailers)
    sim = built_fmu_sim(n_trailers)
    sim.initialize(params, inputs)
    for _k in range(6):
        for _ in range(20):
            sim.step(0.01)
        v0, w0 = sim.real("v[0]"), sim.real("w[0]")
        tau = params["robot_tau"]
        inputs = {
            "v_cmd": v0 + rng.uniform(-0.9, 0.9) * params["robot_acc_max"] * tau,
            "w_cmd": w0 + rng.uniform(-0.9, 0.9) * params["robot_alpha_max"] * tau,
            "push_x": rng.uniform(-30, 30), "push_y": rng.uniform(-30, 30),
        }
        before = sim.array("F_lat")
        sim.set(inputs)  # no step: outputs must already reflect the new inputs
        after = assert_forces_match(sim, params, inputs, n_trailers)
        assert np.max(np.abs(after - before)) > 1e-3


@pytest.mark.parametrize("n_trailers", [1, 2, 3, 4, 5])
def test_straight_chain_spin_up_closed_form(built_fmu_sim, n_trailers):
    """At rest, straight, D = F = R, robot yaw acceleration alpha: F_d,i alternates in sign."""
    link, inertia, tau, w_cmd = 0.52, 3.5083, 0.05, 0.05
    alpha = w_cmd / tau  # 1 rad/s^2, below robot_alpha_max = 2
    heading = 0.7
    params = {"robot_tau": tau, "robot_alpha_max": 2.0}
    for i in range(1, n_trailers + 1):
        params.update({f"front[{i}]": link, f"rear[{i - 1}]": link, f"inertia[{i}]": inertia,
                       f"payload[{i}]": 10.0 * i, f"theta_start[{i}]": heading})
    params["theta_start[0]"] = heading
    sim = built_fmu_sim(n_trailers)
    sim.initialize(params, {"w_cmd": w_cmd})
    i = np.arange(1, n_trailers + 1)
    expected = (-1.0) ** (i + 1) * (inertia * alpha / link) * (1 + 2 * (n_trailers - i))
    np.testing.assert_allclose(sim.array("F_lat"), expected, rtol=1e-10, atol=1e-10)


def test_friction_limit_and_slipping_flags(built_fmu_sim):
    n = 4
    rng = np.random.default_rng(700)
    seen = set()
    for trial in range(12):
        params, inputs = random_case(rng, n)
        # spread the friction so that some wheels slide and some do not
        for i in range(1, n + 1):
            params[f"mu[{i}]"] = float(rng.choice([0.0, 0.002, 0.01, 0.05, 0.5]))
        params["g"] = float(rng.choice([9.81, 1.62]))
        sim = built_fmu_sim(n, instance_name=f"t{trial}")
        sim.initialize(params, inputs)
        mu = np.array([params[f"mu[{i}]"] for i in range(1, n + 1)])
        mass = np.array([params[f"mass[{i}]"] + params[f"payload[{i}]"] for i in range(1, n + 1)])
        limit = mu * mass * params["g"]
        np.testing.assert_allclose(sim.array("F_lat_max"), limit, rtol=1e-12, atol=1e-12)
        lateral = sim.array("F_lat")
        flags = sim.array("slipping")
        np.testing.assert_array_equal(flags, np.abs(lateral) > sim.array("F_lat_max"))
        seen.update(bool(f) for f in flags)
        sim.free()
    assert seen == {True, False}


def test_jackknifed_flag(built_fmu_sim):
    n = 3
    for phi2, phi_max, expected in ((0.5, 0.6, False), (0.7, 0.6, True), (-0.7, 0.6, True),
                                    (1.2, 1.5707963267948966, False)):
        sim = built_fmu_sim(n, instance_name=f"p{phi2}")
        sim.initialize({"phi_max": phi_max, "theta_start[0]": 0.2, "theta_start[1]": 0.2,
                        "theta_start[2]": 0.2 - phi2, "theta_start[3]": 0.2 - phi2})
        assert sim.get(["jackknifed"]) == [expected], (phi2, phi_max)
        sim.free()


def sliding_velocities(theta, v0, w0, front, rear, slide):
    """Axle velocity vectors (n+1, 2) and yaw rates (n+1,) when trailer i's wheels slide
    sideways at ``slide[i-1]`` [m/s] along n_i (the robot's do not): P_i = H_i - F_i e_i with
    dP_i = v_i e_i + u_i n_i. Complex arithmetic works (for the complex step)."""
    n = len(theta) - 1
    vel = [v0 * np.array([np.cos(theta[0]), np.sin(theta[0])])]
    rate = [w0]
    for i in range(1, n + 1):
        n_prev = np.array([-np.sin(theta[i - 1]), np.cos(theta[i - 1])])
        hitch_vel = vel[i - 1] - rear[i - 1] * rate[i - 1] * n_prev
        e_i = np.array([np.cos(theta[i]), np.sin(theta[i])])
        n_i = np.array([-np.sin(theta[i]), np.cos(theta[i])])
        u = slide[i - 1]
        rate.append((hitch_vel @ n_i - u) / front[i - 1])
        vel.append((hitch_vel @ e_i) * e_i + u * n_i)
    return np.array(vel), np.array(rate)


def sliding_accelerations(theta, v0, w0, dv0, dw0, front, rear, slide):
    """Axle and yaw accelerations by complex step along the motion, the slides held constant."""
    _, rate = sliding_velocities(theta, v0, w0, front, rear, slide)
    eps = COMPLEX_STEP
    vel_c, rate_c = sliding_velocities(theta + 1j * eps * rate, v0 + 1j * eps * dv0,
                                       w0 + 1j * eps * dw0, front, rear, slide)
    return vel_c.imag / eps, rate_c.imag / eps


@pytest.mark.parametrize("n_trailers", [2, 3, 5])
def test_forces_with_an_imposed_slide_in_a_turn_match_the_global_solve(built_fmu_sim,
                                                                      n_trailers):
    """An imposed sideways slide on every trailer while the train turns: the axle acceleration
    along e_i loses u_i w_i (a_e = dv - u w), which the Newton-Euler forces must carry (with
    n >= 2 the hitch force passes it on to the trailers ahead)."""
    rng = np.random.default_rng(700 + n_trailers)
    for trial in range(3):
        params, inputs = random_case(rng, n_trailers)
        params["w_start"] = 0.45 * (1 if trial % 2 else -1)  # in a turn
        slide = rng.uniform(0.05, 0.25, n_trailers) * rng.choice([-1.0, 1.0], n_trailers)
        inputs.update({f"slide[{i}]": slide[i - 1] for i in range(1, n_trailers + 1)})
        sim = built_fmu_sim(n_trailers, instance_name=f"slide{trial}")
        sim.initialize(params, inputs)
        theta = sim.array("theta")
        v0, w0 = sim.real("v[0]"), sim.real("w[0]")

        def arr(name, first=1, params=params):
            return np.array([params[f"{name}[{i}]"] for i in range(first, first + n_trailers)])

        front, rear = arr("front"), arr("rear", 0)
        mass, inertia = arr("mass") + arr("payload"), arr("inertia")
        dv0 = lag(inputs["v_cmd"], v0, params["robot_tau"], params["robot_acc_max"])
        dw0 = lag(inputs["w_cmd"], w0, params["robot_tau"], params["robot_alpha_max"])
        acc, alpha = sliding_accelerations(np.asarray(theta, float), v0, w0, dv0, dw0, front,
                                           rear, slide)
        push = np.array([inputs["push_x"], inputs["push_y"]])
        hitch, lateral = global_force_solve(theta, acc, alpha, front, rear, mass, inertia, push)
        scale = 1.0 + float(np.max(np.abs(hitch)))
        np.testing.assert_allclose(sim.array("F_lat"), lateral, rtol=1e-9, atol=1e-9 * scale)
        np.testing.assert_allclose(sim.array("hitch_fx"), hitch[:, 0], rtol=1e-9,
                                   atol=1e-9 * scale)
        np.testing.assert_allclose(sim.array("hitch_fy"), hitch[:, 1], rtol=1e-9,
                                   atol=1e-9 * scale)
        # the slide matters here: the same state without it gives other forces
        still, _ = sliding_accelerations(np.asarray(theta, float), v0, w0, dv0, dw0, front,
                                         rear, np.zeros(n_trailers))
        assert np.max(np.abs(still - acc)) > 1e-3
        sim.free()
