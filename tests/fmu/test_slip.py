"""slip_mode = 1: wheels that slide when rolling needs more than Coulomb friction (issue 6)."""

import math

import numpy as np
import pytest

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.openloop import ConstantCommand, RotationProfile
from pushtrain.core.reference import Reference
from pushtrain.core.segment import Segment
from pushtrain.cosim.events import Push
from pushtrain.cosim.master import simulate
from pushtrain.cosim.plant import InitialState, PlantConfig
from pushtrain.table1 import LINK, TRAILER_INERTIA, TRAILER_MASS

M, INERTIA = TRAILER_MASS, TRAILER_INERTIA  # the FMU's start values


AT_REST = InitialState(0.0, 0.0, np.zeros(4))
HOLD = ConstantCommand(3)  # the robot holds still


def lateral_wheel_speeds(theta, w, v0, front=LINK, rear=LINK):
    """Lateral speed of each trailer's axle midpoint along its left normal, from the poses.

    Independent of the FMU's own ``slide_speed``: rigid links P_i = P_{i-1} - R e_{i-1} - F e_i
    give dP_i/dt = dP_{i-1}/dt - R w_{i-1} n_{i-1} - F w_i n_i, with dP_0/dt = v0 e_0 (the robot
    does not slide). ``theta``, ``w``: (..., n+1) arrays; returns (..., n).
    """
    theta, w = np.asarray(theta, float), np.asarray(w, float)
    normal = np.stack([-np.sin(theta), np.cos(theta)], axis=-1)
    velocity = np.asarray(v0, float)[..., None] * np.stack([np.cos(theta[..., 0]),
                                                            np.sin(theta[..., 0])], axis=-1)
    out = []
    for i in range(1, theta.shape[-1]):
        velocity = (velocity - rear * w[..., i - 1, None] * normal[..., i - 1, :]
                    - front * w[..., i, None] * normal[..., i, :])
        out.append(np.sum(velocity * normal[..., i, :], axis=-1))
    return np.stack(out, axis=-1)


def coulomb_problems(d, n=3, speed_tol=1e-12):
    """Where the recorded wheels break Coulomb's law (empty if nowhere).

    Per trailer and sample: |F_lat| <= limit; a wheel below its limit sticks (lateral speed 0,
    computed from the poses, and not flagged); a sliding wheel is at its limit against its motion.
    """
    theta = np.stack([d[f"theta{i}"] for i in range(n + 1)], axis=-1)
    w = np.stack([d[f"w{i}"] for i in range(n + 1)], axis=-1)
    u_poses = lateral_wheel_speeds(theta, w, d["v0"])
    problems = []
    for i in range(1, n + 1):
        force, limit, u = d[f"F_lat{i}"], d[f"F_lat_max{i}"], u_poses[:, i - 1]
        flagged = d[f"slipping{i}"] > 0.5
        checks = {
            "above the limit": np.abs(force) > limit * (1 + 1e-12),
            "sticks but moves sideways": (np.abs(force) < limit * (1 - 1e-9))
            & (np.abs(u) > speed_tol),
            "sticks but flagged slipping": (np.abs(force) < limit * (1 - 1e-9)) & flagged,
            "slides below the limit": (np.abs(u) > 1e-9) & (np.abs(force) < limit * (1 - 1e-9)),
            "pushes along its sliding": (np.abs(u) > 1e-9) & (force * u > 0),
            "slide_speed differs from the poses": np.abs(d[f"u{i}"] - u) > 1e-12,
        }
        for what, bad in checks.items():
            if np.any(bad):
                k = int(np.argmax(bad))
                problems.append(f"trailer {i} {what} at t = {d['t'][k]:.4f} s ({int(bad.sum())} "
                                f"samples): F = {force[k]:.6g} N of {limit[k]:.6g} N, "
                                f"u = {u[k]:.3g}")
    return problems


def test_below_friction_mode_1_reproduces_mode_0(fmu3):
    rho = 2.5
    ref = Reference.from_segments((0.0, 0.0, math.pi), [Segment("arc", 2 * math.pi * rho, 1 / rho)],
                                  speed=0.08)
    initial = InitialState.behind_reference(ref, PlantConfig(3).geometry(), lateral_offset=0.2)
    cfg = ControllerConfig.uniform(3, acc_max=0.2, alpha_max=math.radians(10.0))
    runs = [simulate(fmu3, ref, cfg, initial=initial, plant=PlantConfig(3, slip_mode=mode),
                     horizon=60.0, check_goal=False) for mode in (0, 1)]
    d0, d1 = runs[0].data, runs[1].data
    assert max(runs[1].summary["max_F_lat_ratio"]) < 1.0  # really below the limit
    for i in range(4):
        assert np.max(np.hypot(d0[f"x{i}"] - d1[f"x{i}"], d0[f"y{i}"] - d1[f"y{i}"])) < 1e-3
    for i in (1, 2, 3):
        assert np.max(np.abs(d0[f"F_lat{i}"] - d1[f"F_lat{i}"])) < 1e-6
        assert not d1[f"slipping{i}"].any()


@pytest.mark.parametrize("force, moves", [(30.0, False), (45.0, True)])
def test_a_push_below_friction_moves_nothing_and_above_it_slides(fmu3, force, moves):
    limit = 0.09 * M * 9.81  # 37.17 N
    result = simulate(fmu3, None, HOLD, initial=AT_REST, plant=PlantConfig(3, slip_mode=1),
                      horizon=4.0, events=[Push(1.0, 2.0, lateral=force)])
    d = result.data
    moved = math.hypot(d["x3"][-1] - d["x3"][0], d["y3"][-1] - d["y3"][0])
    k = int(np.searchsorted(d["t"], 2.0))
    if moves:
        assert moved > 0.05
        assert d["slipping3"][k] == 1.0
        assert abs(d["F_lat3"][k]) == pytest.approx(limit, rel=1e-9)  # sliding: friction saturates
        assert abs(d["u3"][k]) > 1e-3
    else:
        assert moved < 1e-12
        assert d["F_lat3"][k] == pytest.approx(-force)  # the wheel holds the push
        assert not d["slipping3"].any()


def test_sliding_wheels_without_robot_motion_only_lose_energy(fmu3):
    # the robot spins and stops abruptly: the trailers slide on and friction brakes them
    initial = InitialState(0.0, 0.0, np.zeros(4), w0=1.5)
    plant = PlantConfig(3, slip_mode=1, robot_alpha_max=1000.0, robot_tau=0.01)
    d = simulate(fmu3, None, HOLD, initial=initial, plant=plant, horizon=3.0).data
    ke = sum(0.5 * M * (d[f"v{i}"] ** 2 + d[f"u{i}"] ** 2) + 0.5 * INERTIA * d[f"w{i}"] ** 2
             for i in (1, 2, 3))
    still = int(np.searchsorted(d["t"], 0.15))  # robot at rest (|w0| < 1e-6 rad/s) from here
    assert abs(d["w0"][still]) < 1e-5
    # trailers 1 and 2 slide; trailer 3 needs less than friction (34 N of 37 N) and sticks
    assert d["slipping1"][still] and d["slipping2"][still]
    assert not d["slipping3"][still] and abs(d["F_lat3"][still]) < 0.95 * d["F_lat_max3"][0]
    assert coulomb_problems(d) == []
    assert ke[still] > 1.0
    assert np.all(np.diff(ke[still:]) <= 1e-9 * ke[still])
    assert ke[-1] < 1e-6  # and they come to rest


def test_frictionless_sliding_conserves_energy(fmu3):
    # mu = 0: every wheel slides freely; once the robot has stopped nothing does work, so the
    # kinetic energy stays constant up to the first-order time stepping (checks M and the
    # velocity-product terms of the sliding dynamics)
    initial = InitialState(0.0, 0.0, np.array([0.0, 0.3, -0.2, 0.4]), w0=1.0)
    plant = PlantConfig(3, slip_mode=1, mu=0.0, robot_alpha_max=1000.0, robot_tau=0.005,
                        slip_substep=2e-4)
    d = simulate(fmu3, None, HOLD, initial=initial, plant=plant, horizon=4.0).data
    ke = sum(0.5 * M * (d[f"v{i}"] ** 2 + d[f"u{i}"] ** 2) + 0.5 * INERTIA * d[f"w{i}"] ** 2
             for i in (1, 2, 3))
    still = int(np.searchsorted(d["t"], 0.1))
    assert abs(d["w0"][still]) < 1e-6 and ke[still] > 1.0
    assert np.max(np.abs(ke[still:] / ke[still] - 1.0)) < 2e-3


def _rotation(fmu, alpha_deg, payload=(0.0, 0.0, 0.0)):
    profile = RotationProfile(3, math.radians(20.0), math.radians(alpha_deg))
    plant = PlantConfig(3, slip_mode=1, robot_alpha_max=5.0, payload=list(payload))
    return simulate(fmu, None, profile, initial=AT_REST, plant=plant, horizon=6.0).summary


def test_pure_rotation_slips_first_on_trailer_1_as_alpha_grows(fmu3):
    calm = _rotation(fmu3, 5.0)
    assert all(s["events"] == 0 for s in calm["slip"])
    ratios = calm["max_F_lat_ratio"]
    assert ratios[0] > ratios[1] > ratios[2]  # F_d,1 is the largest (paper, Sec. 4.4)
    hard = _rotation(fmu3, 60.0)
    first = [s["first_t"] for s in hard["slip"]]
    assert first[0] is not None
    assert all(t is None or t >= first[0] for t in first[1:])


def test_heavy_payload_on_the_last_trailer_slips_earlier_than_on_trailer_1(fmu3):
    on_first = _rotation(fmu3, 30.0, payload=(80.0, 0.0, 0.0))
    on_last = _rotation(fmu3, 30.0, payload=(0.0, 0.0, 80.0))
    assert all(s["events"] == 0 for s in on_first["slip"])
    assert any(s["events"] > 0 for s in on_last["slip"])


def test_slide_input_is_refused_in_slip_mode_1(fmu3):
    from pushtrain.cosim.events import Slide
    from pushtrain.cosim.fmu_slave import TrailerTrainSlave
    from pushtrain.errors import CosimError

    with pytest.raises(CosimError, match="Push"):
        simulate(fmu3, None, HOLD, initial=AT_REST, plant=PlantConfig(3, slip_mode=1),
                 horizon=1.0, events=[Slide(0.2, 0.5, 0.1)])
    with TrailerTrainSlave(fmu3) as slave:  # and the FMU itself refuses it, naming the input
        slave.start({"slip_mode": 1})
        with pytest.raises(CosimError, match=r"slide\[3\] = 0.2.*push_x"):
            slave.real_writer(["slide[3]"])([0.2])


# -- issue: sticking wheels flagged as slipping; F_lat above the limit ----------------------------
def _run_pushed_while_turning(sim, slip_substep, steps=800, h=0.005):
    """The reported scenario, through the FMU's own inputs: the robot reverses and turns
    (v = -0.1 m/s, w = 0.1 rad/s), trailers 1-2 have mu = 0.5, and a world-frame push_y of 1.5x
    trailer 3's friction limit acts on it from t = 1 s to t = 3 s. Returns a record like the
    master's (outputs at each communication point)."""
    limit = 0.09 * M * 9.81
    sim.initialize({"slip_mode": 1, "mu[1]": 0.5, "mu[2]": 0.5, "slip_substep": slip_substep,
                    "v_start": -0.1, "w_start": 0.1}, {"v_cmd": -0.1, "w_cmd": 0.1})
    names = {f"{b}{i}": f"{b}[{i}]" for b in ("theta", "w") for i in range(4)}
    names.update({f"{b}{i}": f"{b}[{i}]" for b in ("F_lat", "F_lat_max", "slipping")
                  for i in (1, 2, 3)})
    names.update({f"u{i}": f"slide_speed[{i}]" for i in (1, 2, 3)})
    names["v0"] = "v[0]"
    rows = {key: [] for key in ["t", *names]}
    for k in range(steps):
        t = k * h
        sim.set({"push_y": 1.5 * limit if 1.0 <= t < 3.0 else 0.0})
        sim.step(h)
        rows["t"].append(t + h)
        for key, value in zip(names, sim.get(list(names.values())), strict=True):
            rows[key].append(float(value))
    return {key: np.array(values) for key, values in rows.items()}


@pytest.mark.parametrize("slip_substep", [0.0005, 0.000125])
def test_sticking_wheels_stay_stuck_while_the_last_trailer_slides(built_fmu_sim, slip_substep):
    d = _run_pushed_while_turning(built_fmu_sim(3), slip_substep)
    pushed = (d["t"] > 1.05) & (d["t"] <= 3.0)
    # trailer 3 slides at its limit the whole time it is pushed ...
    assert np.all(np.abs(d["u3"][pushed]) > 1e-3)
    np.testing.assert_allclose(np.abs(d["F_lat3"][pushed]), d["F_lat_max3"][pushed], rtol=1e-12)
    # ... while trailers 1 and 2 need at most a fraction of theirs and stay exactly stuck
    for i in (1, 2):
        assert np.max(np.abs(d[f"F_lat{i}"]) / d[f"F_lat_max{i}"]) < 0.6
        assert not np.any(d[f"slipping{i}"]), i
    assert coulomb_problems(d) == []


def test_wheel_forces_never_exceed_friction_even_right_after_new_inputs(built_fmu_sim):
    """Rolling would need more than friction the moment the command jumps (before any step):
    the outputs then show the Coulomb forces of that instant, and a very short step continues
    them (the onset forces are the limit of the sliding forces as the step goes to 0)."""
    sim = built_fmu_sim(3, logging_on=True)
    sim.initialize({"slip_mode": 1, "robot_alpha_max": 50.0, "theta_start[2]": 0.3,
                    "theta_start[3]": -0.2, "v_start": -0.1, "w_start": 0.1},
                   {"v_cmd": -0.1, "w_cmd": 0.1})
    sim.step(0.005)
    limits = sim.array("F_lat_max")
    assert np.all(np.abs(sim.array("F_lat")) < limits)  # rolling within friction
    sim.set({"w_cmd": -1.0})  # yaw acceleration 50 rad/s^2: rolling would need far more
    onset = sim.array("F_lat")
    flags = sim.array("slipping")
    assert np.all(np.abs(onset) <= limits * (1 + 1e-12))
    assert flags.any() and np.all(np.abs(onset[flags]) == pytest.approx(limits[flags], rel=1e-9))
    assert np.max(np.abs(sim.array("slide_speed"))) < 1e-12  # nothing has moved yet
    sim.fmu.doStep(currentCommunicationPoint=sim.time, communicationStepSize=1e-7)
    np.testing.assert_allclose(sim.array("F_lat"), onset, rtol=0, atol=1e-4 * limits.max())


@pytest.mark.parametrize("alpha_deg, payload", [(60.0, (0.0, 0.0, 0.0)),
                                                (120.0, (0.0, 0.0, 80.0)),
                                                (30.0, (0.0, 0.0, 80.0))])
def test_wheels_obey_coulomb_in_a_hard_rotation(fmu3, alpha_deg, payload):
    profile = RotationProfile(3, math.radians(20.0), math.radians(alpha_deg))
    plant = PlantConfig(3, slip_mode=1, robot_alpha_max=5.0, payload=list(payload))
    result = simulate(fmu3, None, profile, initial=AT_REST, plant=plant, horizon=6.0)
    assert result.summary["slip"][0]["events"] > 0  # trailer 1 does slide
    assert coulomb_problems(result.data) == []
