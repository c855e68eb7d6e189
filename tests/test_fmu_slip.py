"""slip_mode = 1: wheels that slide when rolling needs more than Coulomb friction (issue 6)."""

import math

import numpy as np
import pytest

from pushtrain.core.controller import ControllerConfig
from pushtrain.cosim.master import InitialState, PlantConfig, Push, simulate
from pushtrain.core.openloop import ConstantCommand, RotationProfile
from pushtrain.core.reference import Reference, Segment

M, I = 42.1, 3.5083


AT_REST = InitialState(0.0, 0.0, np.zeros(4))
HOLD = ConstantCommand(3)  # the robot holds still


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


def test_all_wheels_sliding_without_robot_motion_only_lose_energy(fmu3):
    # the robot spins and stops abruptly: the trailers slide on and friction brakes them
    initial = InitialState(0.0, 0.0, np.zeros(4), w0=1.5)
    plant = PlantConfig(3, slip_mode=1, robot_alpha_max=1000.0, robot_tau=0.01)
    d = simulate(fmu3, None, HOLD, initial=initial, plant=plant, horizon=3.0).data
    ke = sum(0.5 * M * (d[f"v{i}"] ** 2 + d[f"u{i}"] ** 2) + 0.5 * I * d[f"w{i}"] ** 2
             for i in (1, 2, 3))
    still = int(np.searchsorted(d["t"], 0.15))  # robot at rest (|w0| < 1e-6 rad/s) from here
    assert abs(d["w0"][still]) < 1e-5
    assert all(d[f"slipping{i}"][still] for i in (1, 2, 3))
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
    ke = sum(0.5 * M * (d[f"v{i}"] ** 2 + d[f"u{i}"] ** 2) + 0.5 * I * d[f"w{i}"] ** 2
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
    from pushtrain.cosim.fmu_slave import TrailerTrainSlave
    from pushtrain.cosim.master import CosimError, Slide

    with pytest.raises(CosimError, match="Push"):
        simulate(fmu3, None, HOLD, initial=AT_REST, plant=PlantConfig(3, slip_mode=1),
                 horizon=1.0, events=[Slide(0.2, 0.5, 0.1)])
    with TrailerTrainSlave(fmu3) as slave:  # and the FMU itself refuses it, naming the input
        slave.start({"slip_mode": 1})
        with pytest.raises(CosimError, match=r"slide\[3\] = 0.2.*push_x"):
            slave.real_writer(["slide[3]"])([0.2])
