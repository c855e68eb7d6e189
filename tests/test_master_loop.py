"""The master's compiled step loop (``cosim/csrc/master_loop.c``) against its Python loop.

Each case runs :func:`simulate` twice on the same FMU, ``step_loop="c"`` and
``step_loop="python"`` (the Python loop with the same compiled control law), and asserts the two
runs equal bit for bit: every column of the results table (``np.array_equal`` and the raw
bytes), the status and the message. The cases are chosen so that each feature the compiled loop
reproduces is active in them (checked from the recorded data): noisy, quantized, biased sensors
with play; bias switches; pushes turning with the trailer, while pushing, at a cusp and while
pulling; slip_mode 1 with sliding wheels; imposed slides; a jackknife; the goal; FMU and
control-law failures.
"""

import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from reference.controller import BackwardController

from pushtrain.cli.main import cli
from pushtrain.core.controller import ControllerConfig
from pushtrain.core.governor import GovernedController, GovernorConfig, SlipGovernor
from pushtrain.core.kinematics import ChainGeometry
from pushtrain.core.native_controller import NativeController
from pushtrain.core.reference import PULL, PUSH, REST, Reference, Segment
from pushtrain.cosim import master, step_loop
from pushtrain.cosim.events import Push, SetBias, Slide
from pushtrain.cosim.master import simulate
from pushtrain.cosim.plant import InitialState, PlantConfig
from pushtrain.cosim.sensors import SensorConfig, Sensors
from pushtrain.errors import CosimError
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


def _both(fmu, reference, controller=None, **kwargs):
    """The runs of the compiled and the Python loop, asserted bit-identical; (c, python)."""
    runs = {}
    for loop in ("c", "python"):
        runs[loop] = simulate(fmu, reference, controller or _config(), step_loop=loop,
                              progress=False, **kwargs)
        assert runs[loop].summary["step_loop"] == loop
    c, py = runs["c"], runs["python"]
    assert (c.status, c.message) == (py.status, py.message)
    assert c.data.dtype == py.data.dtype and len(c.data) == len(py.data)
    for name in c.data.dtype.names:
        assert np.array_equal(c.data[name], py.data[name]), name
    assert c.data.tobytes() == py.data.tobytes()  # signed zeros too
    return c, py


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
    runs = {}
    for loop in ("c", "python"):
        runs[loop] = simulate(fmu3, _arc(), _config(), sensors[loop], events, horizon=12.0,
                              check_goal=False, progress=False, step_loop=loop)
    c, py = runs["c"], runs["python"]
    assert (c.status, c.message) == (py.status, py.message)
    assert c.data.tobytes() == py.data.tobytes()
    # the sensors end in the same state: the generator drew exactly the same numbers
    assert sensors["c"].rng.random() == sensors["python"].rng.random()
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
    c, _ = _both(fmu3, _push_pull(), events=events)
    d = c.data
    assert {PUSH, PULL, REST} <= set(d["direction"].astype(int).tolist())
    assert np.count_nonzero(d["push_x"]) > 100 and np.count_nonzero(d["push_y"]) > 100
    # a lateral push turns with the trailer: its direction follows theta3
    lateral = (d["t"] >= 0.5) & (d["t"] < 2.5)
    np.testing.assert_allclose(d["push_x"][lateral], -np.sin(d["theta3"][lateral]) * 25.0,
                               rtol=0, atol=1e-12)


def test_slip_mode_1_with_sliding_wheels_under_pushes(fmu3):
    events = [Push(2.0, 1.0, lateral=60.0), Push(5.0, 0.5, fx=20.0, fy=-40.0)]
    c, _ = _both(fmu3, _arc(2.0, 0.5), plant=PlantConfig(3, slip_mode=1), events=events,
                 horizon=12.0, check_goal=False)
    d = c.data
    assert d["slipping3"].sum() > 100 and d["slipping1"].sum() > 10
    assert np.abs(d["u3"]).max() > 0.1


def test_imposed_slides_in_the_rolling_model(fmu3):
    events = [Slide(2.0, 1.0, -0.15), Slide(2.5, 1.5, 0.1, trailer=1),
              Slide(5.0025, 0.5, 0.05, trailer=3)]
    c, _ = _both(fmu3, _arc(), events=events, horizon=10.0, check_goal=False)
    d = c.data
    assert set(np.round(d["slide"], 12).tolist()) == {0.0, -0.15, 0.1}
    assert np.abs(d["u1"]).max() == pytest.approx(0.1 / 1.5)


def test_a_jackknife_stops_both_loops_at_the_same_step(fmu3):
    ref = Reference.from_segments((0.0, 0.0, math.pi),
                                  [Segment("line", 0.5), Segment("arc", 2.0, 1.5)], speed=0.08)
    c, _ = _both(fmu3, ref, plant=PlantConfig(3, phi_max=math.radians(25.0)))
    assert c.status == "jackknifed" and "phi_max" in c.message
    assert c.data["jackknifed"][-1] == 1.0 and not c.data["jackknifed"][:-1].any()


def test_the_goal_stops_both_loops_and_a_rejected_candidate_steps_on(fmu3, monkeypatch):
    ref = Reference.from_segments((0.0, 0.0, math.pi), [Segment("line", 1.0)], speed=0.08)
    c, _ = _both(fmu3, ref)
    assert c.status == "goal_reached"
    # with a wide slack the C loop hands back candidates that Python's exact test rejects: it
    # steps on from Python and still gives the Python loop's run
    tests = []
    original = master.PythonLoop.goal_reached

    def counting(self, *args):
        tests.append(original(self, *args))
        return tests[-1]

    monkeypatch.setattr(master.PythonLoop, "goal_reached", counting)
    monkeypatch.setattr(step_loop.CompiledLoop, "goal_slack", 50.0)
    initial = InitialState.behind_reference(ref, _config().geometry, lateral_offset=0.1)
    c = simulate(fmu3, ref, _config(), initial=initial, goal_tolerance=(0.004, 0.01),
                 progress=False, step_loop="c")
    rejected = sum(1 for found in tests if found is None)
    py = simulate(fmu3, ref, _config(), initial=initial, goal_tolerance=(0.004, 0.01),
                  progress=False, step_loop="python")
    assert rejected > 1000 and c.status == "goal_not_reached"
    assert (c.status, c.message) == (py.status, py.message)
    assert c.data.tobytes() == py.data.tobytes()


def test_fmu_and_control_law_failures_end_both_loops_alike(fmu3):
    ref = Reference.from_segments((0.0, 0.0, math.pi), [Segment("line", 1.0)], speed=0.08)
    # fmi2DoStep fails (non-finite state), fmi2SetReal refuses an input, the law refuses a
    # non-finite measurement (quantization of 1e-320 rad overflows a noisy reading)
    c, _ = _both(fmu3, ref, plant=PlantConfig(3, slip_mode=1), events=[Push(1.0, 0.1, fx=1e300)])
    assert c.status == "fmu_error" and "fmi2DoStep failed at t = 1.000000 s" in c.message
    assert len(c.data) == 201
    c, _ = _both(fmu3, ref, events=[Push(0.5, 0.1, fx=math.inf)])
    assert c.status == "fmu_error" and c.message.startswith("setting ['v_cmd', 'w_cmd'")
    assert len(c.data) == 100
    sensors = SensorConfig(3, joint_quantization=1e-320, joint_noise=0.01)
    with np.errstate(over="ignore"):
        c, _ = _both(fmu3, ref, sensors=sensors)
    assert c.status == "fmu_error" and "non-finite measurement at t = 0.0 s" in c.message


def test_the_loop_is_chosen_automatically_and_recorded(fmu3):
    ref = _arc(1.0)
    run = simulate(fmu3, ref, _config(), horizon=1.0, progress=False)
    assert run.summary["step_loop"] == "c" and "step_loop_fallback" not in run.summary
    run = simulate(fmu3, ref, BackwardController(_config()), horizon=1.0, progress=False)
    assert run.summary["step_loop"] == "python"
    assert "not the compiled one" in run.summary["step_loop_fallback"]
    gov = SlipGovernor(GovernorConfig(_config().geometry, np.full(3, 42.1), np.full(3, 3.5),
                                      np.full(3, 0.09), fraction=0.8, tau=0.05, acc_max=1.0,
                                      alpha_max=2.0))
    governed = GovernedController(NativeController(_config()), gov, dt=0.005)
    run = simulate(fmu3, ref, governed, horizon=1.0, progress=False)
    assert run.summary["step_loop"] == "python"
    with pytest.raises(CosimError, match=r"step_loop = 'c'.*governor.*'auto' and 'python'"):
        simulate(fmu3, ref, governed, horizon=1.0, progress=False, step_loop="c")
    with pytest.raises(CosimError, match=r"step_loop = 'fast'.*'auto', 'c', 'python'"):
        simulate(fmu3, ref, _config(), step_loop="fast")


def test_a_bad_step_loop_in_a_scenario_exits_2_naming_it(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('[mission]\nkind = "scripted"\n[sim]\nstep_loop = "fortran"\n'
                    '[reference]\nsegments = [{kind = "line", length = 1.0}]\n'
                    '[start]\nx = 0.0\ny = 0.0\n')
    result = CliRunner().invoke(cli, ["plan-and-run", str(path), "--out", str(tmp_path / "o")])
    assert result.exit_code == 2, result.output
    assert "sim.step_loop" in result.output and "fortran" in result.output
    assert "'auto'" in result.output and "Traceback" not in result.output


EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.mark.parametrize("name", ["joint_bias_5deg", "circle", "l_corridor", "slip_governor"])
def test_bundled_examples_run_alike_in_both_loops(name):
    """A scripted run with a joint bias and the last trailer localized, an arc, a planned
    push-pull corridor mission, and the governor (which takes the Python loop under auto)."""
    sc = load_scenario(EXAMPLES / f"{name}.toml")
    reference = None
    if sc.mission.kind == "plan":
        path = plan_path(sc)
        reference = path.to_reference(speed=sc.planner.speed, cusp_dwell=sc.planner.cusp_dwell)
    runs = {}
    for loop in ("auto", "python"):
        scenario = sc.model_copy(update={"sim": sc.sim.model_copy(update={"step_loop": loop})})
        runs[loop] = run_scenario(scenario, reference=reference, progress=False)
    auto, py = runs["auto"], runs["python"]
    assert auto.summary["step_loop"] == ("python" if sc.controller.governor else "c")
    assert (auto.status, auto.message) == (py.status, py.message) == (
        "goal_reached", auto.message)
    assert auto.data.tobytes() == py.data.tobytes()
