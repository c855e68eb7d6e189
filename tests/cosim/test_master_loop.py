"""The master's step loop (``cosim/csrc/master_loop.c``) against the same loop written step by
step in Python (``tests/reference/master_loop.py``).

Each case runs :func:`simulate` and the reference loop on the same FMU and asserts the two runs
equal bit for bit: every column of the results table (``np.array_equal`` and the raw bytes), the
status and the message. The cases are chosen so that each feature the loop has is active in
them (checked from the recorded data): noisy, quantized, biased sensors with play; bias
switches; pushes turning with the trailer, while pushing, at a cusp and while pulling; slip_mode
1 with sliding wheels; imposed slides; a jackknife; the goal; FMU and control-law failures; the
slip governor and open-loop profiles (in C: no call back into Python, for any bundled example)
and a law written in Python (called back from the loop); FMI 2.0 and 3.0.
"""

import math
import struct
from pathlib import Path

import numpy as np
import pytest
from reference import master_loop
from reference.controller import BackwardController

from pushtrain.core.controller import Controller, ControllerConfig
from pushtrain.core.governor import GovernedController, GovernorConfig, SlipGovernor
from pushtrain.core.kinematics import ChainGeometry
from pushtrain.core.openloop import ConstantCommand, RotationProfile
from pushtrain.core.reference import Reference
from pushtrain.core.sampled_reference import SampledReference
from pushtrain.core.segment import PULL, PUSH, REST, Segment
from pushtrain.core.sensors import SensorConfig, Sensors
from pushtrain.cosim import step_loop
from pushtrain.cosim.events import Push, SetBias, Slide
from pushtrain.cosim.master import simulate
from pushtrain.cosim.plant import InitialState, PlantConfig
from pushtrain.fmu.build import build_fmu
from pushtrain.mission.runner import plan_path, run_scenario
from pushtrain.mission.scenario import load_scenario


def _push_pull():
    """Push a line and an arc, cusp (dwell), pull a line and an arc, cusp, push again."""
    return Reference.from_segments((0.0, 0.0, math.pi), [
        Segment("line", 0.4), Segment("arc", 0.5, 0.8), Segment("line", 0.4, 0.0, PULL),
        Segment("arc", 0.4, -0.7, PULL), Segment("line", 0.3)], speed=0.08, cusp_dwell=1.0)


def _arc(length=8.0, curvature=0.4):
    return Reference.from_segments((0.0, 0.0, math.pi), [Segment("arc", length, curvature)],
                                   speed=0.08)


def _config(n=3):
    return ControllerConfig(geometry=ChainGeometry.uniform(n, 0.52), k_x=1.0, k_y=4.0,
                            k_theta=4.0, v_max=0.1, w_max=0.1, acc_max=0.2,
                            alpha_max=math.radians(10.0))


def _same(run, reference_run):
    """Assert a :func:`simulate` run equal to the reference loop's bit for bit."""
    status, message, data = reference_run
    if status is not None:  # the reference loop names the goal, a jackknife and failures
        assert (run.status, run.message) == (status, message)
    else:
        assert run.status in ("completed", "time_limit", "goal_not_reached"), run.message
    assert run.data.dtype == data.dtype and len(run.data) == len(data)
    for name in data.dtype.names:
        assert np.array_equal(run.data[name], data[name], equal_nan=True), name
    assert run.data.tobytes() == data.tobytes()  # signed zeros and NaN bits too


def _both(fmu, reference, controller=None, make=None, **kwargs):
    """The run of the step loop, asserted equal to the reference loop's; ``make`` builds the
    controller afresh for each (a controller keeps state)."""
    build = make or (lambda: controller or _config())
    run = simulate(fmu, reference, build(), progress=False, **kwargs)
    _same(run, master_loop.run(fmu, reference, build(), **kwargs))
    return run


@pytest.mark.parametrize("last_pose", [False, True], ids=["robot_pose", "last_pose"])
def test_noisy_quantized_biased_sensors_with_play_and_bias_switches(fmu3, last_pose,
                                                                    monkeypatch):
    config = SensorConfig(3, joint_bias=[0.0, 0.01, -0.005], joint_noise=math.radians(0.3),
                          joint_quantization=math.radians(0.1),
                          joint_backlash=math.radians(0.6), position_noise=0.003,
                          heading_noise=math.radians(0.3),
                          localize="last_trailer" if last_pose else "robot", seed=11)
    events = [SetBias(3.0, 2, math.radians(3.0)), SetBias(3.0, 1, -0.02),
              SetBias(7.2525, 3, 0.015)]  # two switches at once, one between two steps
    monkeypatch.setattr(step_loop, "CHUNK", 337)  # calls end inside and between the events
    sensors = {loop: Sensors(config) for loop in ("c", "python")}
    kwargs = dict(horizon=12.0, check_goal=False)
    c = simulate(fmu3, _arc(), _config(), sensors["c"], events, progress=False, **kwargs)
    _same(c, master_loop.run(fmu3, _arc(), _config(), sensors["python"], events, **kwargs))
    assert np.array_equal(sensors["c"].play, sensors["python"].play)
    assert np.array_equal(sensors["c"].bias, sensors["python"].bias)
    # what the case is meant to test is active: quantized readings, noise, play, the switches
    d, q = c.data, math.radians(0.1)
    for i in (1, 2, 3):
        meas = d[f"phi_meas{i}"]
        assert np.allclose(meas / q, np.round(meas / q), rtol=0, atol=1e-9)
        assert len(np.unique(meas)) > 20
    assert np.array_equal(sensors["c"].bias, [-0.02, math.radians(3.0), 0.015])
    # the switches show in the readings (up to the play band, 0.6 deg, and the noise)
    late, early = d["t"] > 7.26, (d["t"] > 1.0) & (d["t"] < 2.9)
    offset = lambda i, rows: np.mean(d[f"phi_meas{i}"][rows] - d[f"phi{i}"][rows])  # noqa: E731
    band = math.radians(0.6) + 0.003
    assert offset(2, late) - offset(2, early) == pytest.approx(math.radians(3.0) - 0.01,
                                                                abs=band)
    assert offset(3, late) - offset(3, early) == pytest.approx(0.02, abs=band)


def test_a_push_pull_mission_with_cusps_and_pushes_turning_with_the_trailer(fmu3):
    events = [Push(0.5, 2.0, lateral=25.0), Push(9.0, 4.0, lateral=-30.0, fx=5.0),
              Push(14.0, 0.7525, fy=12.0), SetBias(6.0, 2, math.radians(2.0))]
    c = _both(fmu3, _push_pull(), events=events)
    d = c.data
    assert {PUSH, PULL, REST} <= set(d["direction"].astype(int).tolist())
    assert np.count_nonzero(d["push_x"]) > 100 and np.count_nonzero(d["push_y"]) > 100
    # a lateral push turns with the trailer: its direction follows theta3
    lateral = (d["t"] >= 0.5) & (d["t"] < 2.5)
    np.testing.assert_allclose(d["push_x"][lateral], -np.sin(d["theta3"][lateral]) * 25.0,
                               rtol=0, atol=1e-12)


def test_slip_mode_1_with_sliding_wheels_under_pushes(fmu3):
    events = [Push(2.0, 1.0, lateral=60.0), Push(5.0, 0.5, fx=20.0, fy=-40.0)]
    c = _both(fmu3, _arc(2.0, 0.5), plant=PlantConfig(3, slip_mode=1), events=events,
              horizon=12.0, check_goal=False)
    d = c.data
    assert d["slipping3"].sum() > 100 and d["slipping1"].sum() > 10
    assert np.abs(d["u3"]).max() > 0.1


def test_imposed_slides_in_the_rolling_model(fmu3):
    events = [Slide(2.0, 1.0, -0.15), Slide(2.5, 1.5, 0.1, trailer=1),
              Slide(5.0025, 0.5, 0.05, trailer=3)]
    c = _both(fmu3, _arc(), events=events, horizon=10.0, check_goal=False)
    d = c.data
    assert set(np.round(d["slide"], 12).tolist()) == {0.0, -0.15, 0.1}
    assert np.abs(d["u1"]).max() == pytest.approx(0.1 / 1.5)


def test_a_jackknife_stops_both_loops_at_the_same_step(fmu3):
    ref = Reference.from_segments((0.0, 0.0, math.pi),
                                  [Segment("line", 0.5), Segment("arc", 2.0, 1.5)], speed=0.08)
    c = _both(fmu3, ref, plant=PlantConfig(3, phi_max=math.radians(25.0)))
    assert c.status == "jackknifed" and "phi_max" in c.message
    assert c.data["jackknifed"][-1] == 1.0 and not c.data["jackknifed"][:-1].any()


def test_the_goal_stops_both_loops_and_a_rejected_candidate_steps_on(fmu3, monkeypatch):
    ref = Reference.from_segments((0.0, 0.0, math.pi), [Segment("line", 1.0)], speed=0.08)
    c = _both(fmu3, ref)
    assert c.status == "goal_reached"
    # with a wide slack the C loop hands back candidates that Python's exact test rejects: it
    # steps on from Python and still gives the reference loop's run
    tests = []
    original = step_loop.StepLoop.__init__

    def counting(self, *args):
        original(self, *args)
        test = self.ends.goal_reached
        self.ends.goal_reached = lambda *a: tests.append(test(*a)) or tests[-1]

    monkeypatch.setattr(step_loop.StepLoop, "__init__", counting)
    monkeypatch.setattr(step_loop.StepLoop, "goal_slack", 50.0)
    initial = InitialState.behind_reference(ref, _config().geometry, lateral_offset=0.1)
    c = _both(fmu3, ref, initial=initial, goal_tolerance=(0.004, 0.01))
    rejected = sum(1 for found in tests if found is None)
    assert rejected > 1000 and c.status == "goal_not_reached"


def test_fmu_and_control_law_failures_end_both_loops_alike(fmu3):
    ref = Reference.from_segments((0.0, 0.0, math.pi), [Segment("line", 1.0)], speed=0.08)
    # fmi2DoStep fails (non-finite state), fmi2SetReal refuses an input, the law refuses a
    # non-finite measurement (quantization of 1e-320 rad overflows a noisy reading)
    c = _both(fmu3, ref, plant=PlantConfig(3, slip_mode=1), events=[Push(1.0, 0.1, fx=1e300)])
    assert c.status == "fmu_error" and "fmi2DoStep failed at t = 1.000000 s" in c.message
    assert len(c.data) == 201
    c = _both(fmu3, ref, events=[Push(0.5, 0.1, fx=math.inf)])
    assert c.status == "fmu_error" and c.message.startswith("setting ['v_cmd', 'w_cmd'")
    assert len(c.data) == 100
    sensors = SensorConfig(3, joint_quantization=1e-320, joint_noise=0.01)
    with np.errstate(over="ignore"):
        c = _both(fmu3, ref, sensors=sensors)
    assert c.status == "fmu_error" and "non-finite measurement at t = 0.0 s" in c.message
    # a law written in Python refusing an instant: its own exception ends the run
    with np.errstate(over="ignore"):
        c = _both(fmu3, ref, make=lambda: BackwardController(_config()),
                  events=[Push(0.5, 0.1, fx=1e300)], plant=PlantConfig(3, slip_mode=1))
    assert c.status == "fmu_error", c.message


def _governed():
    gov = SlipGovernor(GovernorConfig(_config().geometry, np.full(3, 42.1), np.full(3, 3.5),
                                      np.full(3, 0.09), fraction=0.8, tau=0.05, acc_max=1.0,
                                      alpha_max=2.0))
    return GovernedController(Controller(_config()), gov, dt=0.005)


def test_the_governor_runs_in_c_and_equals_the_readable_one(fmu3):
    """The slip governor on the compiled law runs inside the C loop (pt_step); the reference loop
    with the readable Python governor (tests/reference/governor.py) gives the same run."""
    from reference import governor as readable

    def governed(governor_class):
        cfg = GovernorConfig(_config().geometry, np.full(3, 42.1), np.full(3, 3.5),
                             np.full(3, 0.09), fraction=0.05)
        return GovernedController(Controller(_config()), governor_class(cfg), dt=0.005)

    law = governed(SlipGovernor)
    run = simulate(fmu3, _push_pull(), law, events=[Push(2.0, 1.0, lateral=30.0)],
                   progress=False)
    want = master_loop.run(fmu3, _push_pull(), governed(readable.SlipGovernor),
                           events=[Push(2.0, 1.0, lateral=30.0)])
    _same(run, want)
    assert law.governor.limited > 1000


@pytest.fixture
def hook_calls(monkeypatch):
    """How often the C loop called back into Python this test (``calls[0]``): the master's
    hook (step_loop.PythonLaw) counted."""
    calls = [0]

    class CountedLaw(step_loop.PythonLaw):
        def _call(self, user, t):
            calls[0] += 1
            return super()._call(user, t)

    monkeypatch.setattr(step_loop, "PythonLaw", CountedLaw)
    return calls


NAN_BITS = struct.pack("<d", math.nan)


def test_open_loop_profiles_run_in_c_without_calling_back(fmu3, hook_calls):
    """A rotation profile (with noisy sensors and a lateral push) and a constant command run
    inside the C loop (pt_step on the profile's table) with no call back into Python, equal to
    the reference loop bit for bit; without a reference the sample's pose and the errors are
    the one NaN of math.nan in every row."""
    rotation = lambda: RotationProfile(3, math.radians(10.0), math.radians(5.0), 0.5)  # noqa: E731
    initial = InitialState(0.0, 0.0, np.zeros(4))
    c = _both(fmu3, None, make=rotation, initial=initial, horizon=9.0,
              sensors=SensorConfig(3, joint_noise=0.002, seed=4),
              events=[Push(2.0, 3.0, lateral=20.0)])
    assert c.status == "completed" and c.data["push_x"].any() and c.data["push_y"].any()
    assert np.abs(c.data["w_cmd"]).max() == pytest.approx(math.radians(10.0))
    assert (c.data["w_cmd"] < 0).any() and np.any(c.data["phi_meas1"] != c.data["phi1"])
    for column in ("x_d", "y_d", "theta_d", "e_lon", "e_lat", "e_theta"):
        assert {c.data[column][k].tobytes() for k in range(len(c.data))} == {NAN_BITS}, column
    c = _both(fmu3, None, make=lambda: ConstantCommand(3, -0.05, 0.01), initial=initial,
              horizon=3.0)
    assert set(c.data["v_cmd"]) == {-0.05} and c.data["x3"][-1] < -0.1
    assert hook_calls[0] == 0


def test_laws_written_in_python_are_called_back_from_the_loop(fmu3, hook_calls):
    """The tests' Python law and the compiled law on a sampled reference run in the one loop
    through the hook, once per step; the slip governor on the compiled law does not."""
    c = _both(fmu3, _push_pull(), make=_governed, events=[Push(2.0, 1.0, lateral=30.0)],
              sensors=SensorConfig(3, joint_noise=0.002, seed=4))
    assert len(c.data) > 2000 and hook_calls[0] == 0
    c = _both(fmu3, _push_pull(), make=lambda: BackwardController(_config()),
              events=[Push(9.0, 4.0, lateral=-30.0)])
    assert PULL in c.data["direction"] and c.data["push_x"].any()
    assert hook_calls[0] == len(c.data)
    sampled = SampledReference.from_reference(_arc(2.0), 0.05)
    c = _both(fmu3, sampled, horizon=6.0, check_goal=False)
    assert np.isfinite(c.data["e_lat"]).all()


def test_an_fmi3_fmu_runs_the_same_loop(fmu3):
    """The FMI 3.0 FMU (array variables, read whole and gathered) through the same C loop: the
    reference loop's run, and the FMI 2.0 FMU's."""
    fmu_v3 = Path(build_fmu(fmi_version=3))
    events = [Push(0.5, 2.0, lateral=25.0), Slide(4.0, 1.0, 0.05, trailer=2),
              SetBias(6.0, 2, math.radians(2.0))]
    sensors = SensorConfig(3, joint_noise=0.002, position_noise=0.003, seed=7)
    c3 = _both(fmu_v3, _push_pull(), events=events, sensors=sensors, horizon=12.0,
               check_goal=False)
    c2 = simulate(fmu3, _push_pull(), _config(), sensors, events, horizon=12.0,
                  check_goal=False, progress=False)
    assert c3.data.tobytes() == c2.data.tobytes()
    assert c3.data["u2"].any() and c3.data["push_x"].any()


EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@pytest.mark.parametrize("name", ["joint_bias_5deg", "circle", "l_corridor", "slip_governor"])
def test_bundled_examples_run_alike_in_the_reference_loop(name, hook_calls):
    """A scripted run with a joint bias and the last trailer localized, an arc, a planned
    push-pull corridor mission, and the governor."""
    from pushtrain.mission.runner import (
        controller_of,
        events_of,
        goal_tolerance_of,
        governed,
        initial_of,
        plant_of,
        scripted_reference,
        sensors_of,
    )

    sc = load_scenario(EXAMPLES / f"{name}.toml")
    if sc.mission.kind == "plan":
        path = plan_path(sc)
        reference = path.to_reference(speed=sc.planner.speed, cusp_dwell=sc.planner.cusp_dwell)
    else:
        reference = scripted_reference(sc)
    run = run_scenario(sc, reference=reference, progress=False)
    controller = controller_of(sc)
    if sc.controller.governor:
        controller = governed(sc, controller)
    want = master_loop.run(
        build_fmu(sc.train.n), reference, controller, sensors_of(sc), events_of(sc),
        plant=plant_of(sc), initial=initial_of(sc, reference), step=sc.sim.step,
        horizon=sc.sim.horizon, settle_time=sc.sim.settle_time,
        goal_tolerance=goal_tolerance_of(sc))
    assert run.status == "goal_reached"
    _same(run, want)
    assert hook_calls[0] == 0  # the master ran it without calling back into Python


@pytest.mark.parametrize("path", sorted(EXAMPLES.glob("*.toml")), ids=lambda p: p.stem)
def test_no_bundled_example_calls_back_into_python(path, hook_calls):
    """Each example's co-simulation (a planned example's with a straight reference in place of
    its plan: the runner builds its controller the same way) makes no call back into Python:
    its law, governor or open-loop profile runs in the C loop."""
    sc = load_scenario(path)
    assert sc.mission.kind in ("plan", "scripted", "rotation")
    reference = None
    if sc.mission.kind == "plan":
        start = (sc.start.x, sc.start.y, math.radians(sc.start.theta_deg))
        reference = Reference.from_segments(start, [Segment("line", 0.05)], speed=0.08)
    run = run_scenario(sc, reference=reference, progress=False)
    assert len(run.data) > 1 and hook_calls[0] == 0
