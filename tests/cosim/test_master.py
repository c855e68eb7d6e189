"""Closed loop through the real FMU: the paper's experiments (Sec. 4.2-4.3) and the master's
contract."""

import json
import math

import numpy as np
import pytest

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.openloop import ConstantCommand
from pushtrain.core.reference import Reference
from pushtrain.core.segment import Segment
from pushtrain.core.sensors import SensorConfig
from pushtrain.cosim.events import Push, SetBias, Slide
from pushtrain.cosim.master import simulate
from pushtrain.cosim.plant import InitialState, PlantConfig
from pushtrain.errors import ControllerError, CosimError, ReferencePathError

D = 0.52


def _at(data, t):
    return int(np.searchsorted(data["t"], t - 1e-9))


def test_open_loop_pushing_diverges_and_the_closed_loop_holds(fmu3):
    geom = PlantConfig(n_trailers=3).geometry()
    straight = Reference.from_segments((0.0, 0.0, math.pi), [Segment("line", 4.0)], speed=0.08)
    initial = InitialState.behind_reference(straight, geom,
                                            joint_angles=np.radians([0.0, 0.0, 1.0]))
    open_loop = simulate(fmu3, None, ConstantCommand(3, -0.08), initial=initial, horizon=50.0)
    closed = simulate(fmu3, straight, ControllerConfig.uniform(3), initial=initial, horizon=50.0,
                      check_goal=False)
    phi_open = np.degrees(np.abs([open_loop.data[f"phi{i}"][-1] for i in (1, 2, 3)]))
    phi_closed = np.degrees(np.abs([closed.data[f"phi{i}"][-1] for i in (1, 2, 3)]))
    # open loop: the 1 deg offset grows (or jackknifes); closed loop: the chain straightens
    assert open_loop.status == "jackknifed" or phi_open.max() > 20.0, phi_open
    assert phi_closed.max() < 0.5, phi_closed
    assert abs(closed.data["e_lat"][-1]) < 0.01


def test_straight_corridor_disturbance_is_rejected_fig9(fmu3, tmp_path):
    ref = Reference.from_segments((0.0, 0.0, math.pi), [Segment("line", 12.0)], speed=0.08)
    result = simulate(fmu3, ref, ControllerConfig.uniform(3),
                      events=[Slide(40.0, 1.0, -0.15)], out_dir=tmp_path)
    d = result.data
    before = np.abs(d["e_lat"][: _at(d, 40.0)]).max()
    peak = np.abs(d["e_lat"][_at(d, 40.0): _at(d, 60.0)]).max()
    assert before < 1e-3
    assert peak > 0.12  # the shove moved the last trailer about 15 cm
    late = _at(d, 110.0)
    assert np.abs(d["e_lat"][late:]).max() < 0.01
    for i in (1, 2, 3):
        assert abs(math.degrees(d[f"phi{i}"][-1])) < 0.5
    assert result.status == "goal_reached"
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert (summary["status"] == "goal_reached"
            and summary["lateral_error_m"]["max"] == pytest.approx(peak))
    assert not (tmp_path / "results.csv").exists()  # the CSV only on request (Result.save)
    result.save(tmp_path, csv=True)
    assert (tmp_path / "results.csv").read_text().splitlines()[0].startswith("t,x0,")
    npz = np.load(tmp_path / "results.npz")
    assert np.array_equal(npz["e_lat"], d["e_lat"])


def test_circle_pushed_backward_converges_to_the_steady_joint_angle_fig11(fmu3):
    rho = 2.5
    ref = Reference.from_segments((0.0, 0.0, math.pi), [Segment("arc", 2 * math.pi * rho, 1 / rho)],
                                  speed=0.08)
    geom = PlantConfig(n_trailers=3).geometry()
    initial = InitialState.behind_reference(ref, geom, lateral_offset=0.2)
    result = simulate(fmu3, ref, ControllerConfig.uniform(3), initial=initial, horizon=120.0,
                      check_goal=False)
    d = result.data
    k60 = _at(d, 60.0)
    assert abs(d["e_lat"][0]) == pytest.approx(0.2, abs=1e-9)
    assert np.abs(d["e_lat"][k60:]).max() < 0.01
    expected = math.degrees(2 * math.atan(D / rho))  # 23.50 deg
    assert expected == pytest.approx(23.50, abs=0.005)
    for i in (1, 2, 3):
        assert abs(math.degrees(d[f"phi{i}"][-1])) == pytest.approx(expected, abs=0.1)


def test_push_force_in_rolling_mode_changes_forces_not_motion(fmu3):
    ref = Reference.from_segments((0.0, 0.0, math.pi), [Segment("line", 1.0)], speed=0.08)
    quiet = simulate(fmu3, ref, ControllerConfig.uniform(3), horizon=10.0, check_goal=False)
    pushed = simulate(fmu3, ref, ControllerConfig.uniform(3), horizon=10.0, check_goal=False,
                      events=[Push(2.0, 3.0, lateral=30.0)])
    assert np.array_equal(quiet.data["y3"], pushed.data["y3"])
    k = _at(pushed.data, 3.0)
    # the push acts on the last trailer's axle along its left normal: its wheel takes it
    assert pushed.data["F_lat3"][k] - quiet.data["F_lat3"][k] == pytest.approx(-30.0, abs=1e-6)


def test_bias_event_switches_on_during_the_run(fmu3):
    ref = Reference.from_segments((0.0, 0.0, math.pi), [Segment("line", 2.0)], speed=0.08)
    result = simulate(fmu3, ref, ControllerConfig.uniform(3), horizon=5.0, check_goal=False,
                      events=[SetBias(2.0, 3, math.radians(5.0))])
    d = result.data
    before, after = _at(d, 1.99), _at(d, 2.0)
    assert d["phi_meas3"][before] == pytest.approx(d["phi3"][before])
    assert d["phi_meas3"][after] - d["phi3"][after] == pytest.approx(math.radians(5.0))


def test_bad_configuration_is_refused_before_any_stepping(fmu3):
    ref = Reference.from_segments((0.0, 0.0, math.pi), [Segment("line", 1.0)], speed=0.08)
    with pytest.raises(ControllerError):
        simulate(fmu3, ref, ControllerConfig.uniform(3, k_y=0.0))
    with pytest.raises(CosimError, match="does not divide"):
        simulate(fmu3, ref, ControllerConfig.uniform(3), step=0.005, horizon=1.0012)
    with pytest.raises(CosimError, match="n = 3"):
        simulate(fmu3, ref, ControllerConfig.uniform(2))
    with pytest.raises(CosimError, match="trailer"):
        simulate(fmu3, ref, ControllerConfig.uniform(3), events=[Slide(1.0, 1.0, 0.1, trailer=4)])
    with pytest.raises(ReferencePathError):
        Reference.from_segments((0.0, 0.0, math.pi), [Segment("line", -1.0)])


def test_reference_with_a_jump_is_refused():
    from pushtrain.core.sampled_reference import SampledReference

    t = np.arange(0.0, 2.0, 0.1)
    x = -0.08 * t
    x[10:] += 0.5  # a jump of 0.5 m
    with pytest.raises(ReferencePathError):
        SampledReference(t, x, np.zeros_like(t), np.full_like(t, math.pi), np.full_like(t, -0.08),
                         np.zeros_like(t), np.ones_like(t, dtype=int))


def test_jackknife_stops_the_run_with_a_clear_status(fmu3):
    geom = PlantConfig(n_trailers=3).geometry()
    straight = Reference.from_segments((0.0, 0.0, math.pi), [Segment("line", 4.0)], speed=0.08)
    initial = InitialState.behind_reference(straight, geom,
                                            joint_angles=np.radians([0.0, 0.0, 5.0]))
    result = simulate(fmu3, None, ConstantCommand(3, -0.1), initial=initial, horizon=200.0,
                      plant=PlantConfig(n_trailers=3, phi_max=math.radians(45.0)))
    assert result.status == "jackknifed"
    assert "phi_max" in result.message
    assert result.data["t"][-1] < 200.0


@pytest.mark.parametrize("bias_deg, joint", [(5.0, 3), (10.0, 3), (5.0, 2)])
def test_joint_bias_steady_offset_matches_the_analysis_fig14(fmu3, bias_deg, joint):
    from pushtrain.core import analysis

    biases = np.zeros(3)
    biases[joint - 1] = math.radians(bias_deg)
    sensors = SensorConfig(n_joints=3, joint_bias=biases, localize="last_trailer")
    ref = Reference.from_segments((0.0, 0.0, math.pi), [Segment("line", 14.0)], speed=0.08)
    cfg = ControllerConfig.uniform(3)
    result = simulate(fmu3, ref, cfg, sensors, horizon=170.0, check_goal=False)
    offset = float(np.mean(result.data["e_lat"][_at(result.data, 150.0):]))
    predicted = analysis.steady_lateral_error(analysis.effective_bias(biases), D, cfg.k_y)
    assert offset == pytest.approx(predicted, rel=0.02)
    # a bias on joint 2 of 3 enters with the opposite sign (alternating sum)
    assert math.copysign(1.0, offset) == (-1.0 if joint == 3 else 1.0)
    assert result.status == "completed"
    assert max(abs(math.degrees(result.data[f"phi{i}"][-1])) for i in (1, 2, 3)) < 15.0


def test_a_sampled_reference_drives_the_same_run_as_its_segments(fmu3):
    from pushtrain.core.sampled_reference import SampledReference

    ref = Reference.from_segments((0.0, 0.0, math.pi),
                                  [Segment("line", 0.5), Segment("arc", 0.5, 0.8)], speed=0.08)
    sampled = SampledReference.from_reference(ref, 0.005)
    a = simulate(fmu3, ref, ControllerConfig.uniform(3))
    b = simulate(fmu3, sampled, ControllerConfig.uniform(3))
    assert a.status == b.status == "goal_reached"
    assert np.max(np.abs(a.data["x3"] - b.data["x3"][: len(a.data)])) < 1e-3


def test_the_lateral_push_turns_with_the_trailer_and_ends_on_time(fmu3):
    """On an arc, in the rolling model, the last trailer's wheel takes exactly -lateral at every
    step of the push although the trailer turns (a force fixed at the push's start would give
    -lateral cos(turn)); the recorded force is zero from t0 + duration on."""
    ref = Reference.from_segments((0.0, 0.0, math.pi), [Segment("arc", 2.0, 1 / 1.5)], speed=0.08)
    kwargs = dict(horizon=16.0, check_goal=False)
    quiet = simulate(fmu3, ref, ControllerConfig.uniform(3), **kwargs)
    pushed = simulate(fmu3, ref, ControllerConfig.uniform(3),
                      events=[Push(2.0, 10.0, lateral=30.0)], **kwargs)
    d, t = pushed.data, pushed.data["t"]
    on = (t >= 2.0 - 1e-9) & (t < 12.0 - 1e-9)
    assert np.ptp(d["theta3"][on]) > 0.25  # the trailer turns by more than 14 deg
    assert np.allclose(d["F_lat3"][on] - quiet.data["F_lat3"][on], -30.0, atol=1e-6)
    assert np.array_equal(d["F_lat3"][~on], quiet.data["F_lat3"][~on])
    # the recorded force is the push along the current left normal, exactly zero outside
    assert np.allclose(d["push_x"][on], -np.sin(d["theta3"][on]) * 30.0, rtol=0, atol=1e-12)
    assert np.allclose(d["push_y"][on], np.cos(d["theta3"][on]) * 30.0, rtol=0, atol=1e-12)
    end = _at(d, 12.0)
    assert t[end] == pytest.approx(12.0) and np.all(d["push_x"][end:] == 0.0)
    assert np.all(d["push_y"][end:] == 0.0) and d["push_y"][end - 1] != 0.0


def test_a_huge_horizon_costs_only_the_steps_run(fmu3):
    """horizon = 1e9 s (2e11 steps) with a goal reached after a few steps allocates little."""
    import tracemalloc

    ref = Reference.from_segments((0.0, 0.0, math.pi), [Segment("line", 0.02)], speed=0.08)
    tracemalloc.start()
    try:
        result = simulate(fmu3, ref, ControllerConfig.uniform(3), horizon=1e9, progress=False)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert result.status == "goal_reached" and len(result.data) < 100
    assert peak < 20e6, f"peak {peak / 1e6:.1f} MB"


@pytest.mark.parametrize("with_events", [False, True])
def test_each_row_is_the_fmu_after_the_inputs_of_its_time(with_events, fmu3, built_fmu_sim):
    """A plain fmpy instance fed the recorded inputs at the recorded times gives every recorded
    output and flag bit for bit: the row holds the outputs read after the inputs were set
    (the wheel forces depend directly on them) and nothing of another step."""
    n = 3
    ref = Reference.from_segments((0.0, 0.0, math.pi), [Segment("arc", 2.0, 0.4)], speed=0.08)
    bias = [0.02, -0.01, 0.03]
    events = [Push(1.0, 0.5, lateral=30.0, fx=5.0), Slide(2.0, 0.5, 0.05, trailer=2),
              SetBias(1.5, 1, -0.02)] if with_events else []
    result = simulate(fmu3, ref, ControllerConfig.uniform(n), horizon=4.0, check_goal=False,
                      sensors=SensorConfig(n_joints=n, joint_bias=bias), events=events)
    d = result.data
    assert result.ok and len(d) == 801
    sim = built_fmu_sim(n)
    initial = InitialState.behind_reference(ref, PlantConfig(n_trailers=n).geometry())
    sim.initialize(params=initial.start_values())
    blocks = [("x", "x", 0), ("y", "y", 0), ("theta", "theta", 0), ("v", "v", 0),
              ("w", "w", 0), ("phi", "phi", 1), ("F_lat", "F_lat", 1), ("slide_speed", "u", 1),
              ("slipping", "slipping", 1)]
    slides = np.zeros(n + 1)
    for k in range(len(d)):
        assert d["t"][k] == k * 0.005  # t0 + k h, never a sum
        sim.set({"v_cmd": d["v_cmd"][k], "w_cmd": d["w_cmd"][k],
                 "push_x": d["push_x"][k], "push_y": d["push_y"][k]})
        if with_events and 2.0 - 1e-9 <= d["t"][k] < 2.5 - 1e-9:
            slides[2] = 0.1  # 0.05 m over 0.5 s, trailer 2
        else:
            slides[2] = 0.0
        sim.set({"slide[2]": slides[2]})
        for fmu_name, column, first in blocks:
            got = sim.array(fmu_name).astype(float)
            want = np.array([d[f"{column}{i}"][k] for i in range(first, n + 1)])
            assert np.array_equal(got, want), (k, fmu_name)
        assert d["jackknifed"][k] == float(sim.get(["jackknifed"])[0])
        assert np.array_equal([d[f"F_lat_max{i}"][k] for i in range(1, n + 1)],
                              sim.array("F_lat_max"))
        joint_bias = np.array(bias)
        if with_events and d["t"][k] >= 1.5 - 1e-9:
            joint_bias[0] = -0.02
        assert np.array_equal([d[f"phi_meas{i}"][k] for i in range(1, n + 1)],
                              sim.array("phi") + joint_bias)
        if k < len(d) - 1:
            sim.fmu.doStep(currentCommunicationPoint=float(d["t"][k]), communicationStepSize=0.005)
    assert with_events == bool(np.any(d["push_x"] != 0.0) and np.any(d["u2"] != 0.0))
