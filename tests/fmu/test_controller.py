"""The BackwardController FMU: pushtrain's control law (core/csrc/control.c) behind FMI 2.0.

Held against the Python controller (core/controller.py via core/tracking.py and the sensor model
of core/sensors.py) on random references, chains, parameters and states, through the FMU's own
interface; and checked as an FMU: fmpy's validation, the mode and input guards, the resource
URI forms importers pass, and the mission table's errors.
"""

from __future__ import annotations

import math
import shutil
import zipfile
from ctypes import byref
from pathlib import Path

import numpy as np
import pytest
from conftest import TrailerSim
from reference.controller import BackwardController

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.kinematics import ChainGeometry, body_positions, wrap_scalar
from pushtrain.core.reference import Reference
from pushtrain.core.segment import PULL, PUSH, Segment
from pushtrain.core.sensors import SensorConfig, Sensors
from pushtrain.core.tracking import TrackingLoop
from pushtrain.errors import FmuInputError
from pushtrain.fmu.controller import ControllerTable, build_controller_fmu, render_table
from pushtrain.fmu.controller_variables import controller_variables

fmpy = pytest.importorskip("fmpy")
from fmpy import extract, read_model_description  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402

MODES = {"rest": 0, "push": 1, "pull": 2}
STRAIGHT = ControllerTable((0.0, 0.0, math.pi), (Segment("line", 2.0, 0.0, PUSH),), 0.08,
                           1.0)


def table_of(reference: Reference, geometry: ChainGeometry) -> ControllerTable:
    """The mission table of ``reference`` (as pushtrain.mission.ssp writes it)."""
    from pushtrain.mission.ssp import controller_table

    return controller_table(reference, ControllerConfig(geometry=geometry))


@pytest.fixture
def controller_sim(tmp_path):
    """Factory ``controller_sim(n, table, **kw) -> TrailerSim`` of a controller FMU with that
    mission (instantiated; freed at teardown)."""
    made = []

    def make(n: int, table: ControllerTable, **kwargs) -> TrailerSim:
        path = build_controller_fmu(n, table, tmp_path / f"c{len(made)}.fmu", strict=True)
        unzipdir = extract(str(path), unzipdir=str(tmp_path / f"c{len(made)}"))
        sim = TrailerSim(unzipdir, read_model_description(str(path)), **kwargs)
        made.append(sim)
        return sim

    yield make
    for sim in reversed(made):
        sim.free()


@pytest.mark.parametrize("n", [1, 3])
def test_fmpy_validates_the_controller_fmu(tmp_path, n):
    from fmpy.validation import validate_fmu

    path = build_controller_fmu(n, STRAIGHT, tmp_path / "c.fmu", strict=True)
    assert validate_fmu(str(path)) == []
    with zipfile.ZipFile(path) as zf:
        names = set(zf.namelist())
    assert {"resources/reference.txt", "sources/control.c", "sources/ctrl_instance.c",
            "sources/instance.c", "sources/fmi2.c", "sources/build_config.h",
            "binaries/linux64/BackwardController.so"} <= names


def test_model_description_follows_the_variable_table(controller_sim):
    sim = controller_sim(2, STRAIGHT)
    rows = controller_variables(2)
    assert [v.name for v in sim.md.modelVariables] == [v.name for v in rows]
    assert [v.valueReference for v in sim.md.modelVariables] == [v.vr for v in rows]
    # the C start values are the XML's (read back in Instantiated mode)
    for var in sim.md.modelVariables:
        if var.start is not None and var.causality in ("parameter", "input"):
            got = sim.get([var.name])[0]
            expected = {"Real": float, "Boolean": lambda s: s == "true"}[var.type](var.start)
            assert got == expected, var.name


# ------------------------------------------------------------------ C equals Python

def _random_reference(rng) -> Reference:
    segments = []
    for _ in range(int(rng.integers(2, 6))):
        direction = PUSH if rng.random() < 0.6 else PULL
        speed = None if rng.random() < 0.5 else float(rng.uniform(0.04, 0.12))
        if rng.random() < 0.4:
            segments.append(Segment("line", float(rng.uniform(0.3, 2.0)), 0.0, direction, speed))
        else:
            kappa = float(rng.choice([-1, 1]) * rng.uniform(0.3, 1.5))
            segments.append(Segment("arc", float(rng.uniform(0.3, 2.0)), kappa, direction, speed))
    start = (float(rng.uniform(-5, 5)), float(rng.uniform(-5, 5)), float(rng.uniform(-4, 4)))
    return Reference.from_segments(start, segments, speed=float(rng.uniform(0.05, 0.1)),
                                   cusp_dwell=float(rng.choice([0.0, 0.7])),
                                   t0=float(rng.uniform(-2, 2)))


def _random_config(rng, n: int) -> tuple[ControllerConfig, dict]:
    geometry = ChainGeometry(rng.uniform(0.3, 0.8, n), rng.uniform(0.3, 0.8, n))
    acc = None if rng.random() < 0.3 else float(rng.uniform(0.05, 1.0))
    alpha = None if rng.random() < 0.3 else float(rng.uniform(0.05, 1.0))
    config = ControllerConfig(geometry=geometry, k_x=float(rng.uniform(0.5, 3)),
                              k_y=float(rng.uniform(1, 8)), k_theta=float(rng.uniform(1, 6)),
                              v_max=float(rng.uniform(0.05, 0.3)),
                              w_max=float(rng.uniform(0.05, 0.5)), acc_max=acc, alpha_max=alpha)
    sensor = {"bias": rng.uniform(-0.1, 0.1, n),
              "quantization": float(rng.choice([0.0, math.radians(0.1)])),
              "backlash": float(rng.choice([0.0, math.radians(0.5)])),
              "last": bool(rng.random() < 0.5)}
    return config, sensor


def _parameters(config: ControllerConfig, sensor: dict, v_start, w_start, dt_start) -> dict:
    n = config.geometry.n
    out = {"k_x": config.k_x, "k_y": config.k_y, "k_theta": config.k_theta,
           "v_max": config.v_max, "w_max": config.w_max, "acc_max": config.acc_max or 0.0,
           "alpha_max": config.alpha_max or 0.0, "joint_quantization": sensor["quantization"],
           "joint_backlash": sensor["backlash"], "measure_last_pose": sensor["last"],
           "v_start": v_start, "w_start": w_start, "dt_start": dt_start}
    for i in range(1, n + 1):
        out[f"front[{i}]"] = config.geometry.front[i - 1]
        out[f"rear[{i - 1}]"] = config.geometry.rear[i - 1]
        out[f"joint_bias[{i}]"] = sensor["bias"][i - 1]
    return out


def _random_state(rng, reference: Reference, geometry: ChainGeometry, t: float):
    """A chain near the reference at ``t``: (robot pose, true joint angles, last pose)."""
    ref = reference.sample_at(t)
    n = geometry.n
    x_n = ref.x + rng.normal(0, 0.15)
    y_n = ref.y + rng.normal(0, 0.15)
    th_n = ref.theta + rng.normal(0, 0.2)
    phi = rng.uniform(-0.6, 0.6, n)
    theta = th_n + np.concatenate((np.cumsum(phi[::-1])[::-1], [0.0]))
    xs, ys = body_positions(x_n, y_n, theta, geometry, from_last=True)
    return (float(xs[0]), float(ys[0]), float(theta[0])), phi, (x_n, y_n, th_n)


def _python_outputs(loop, sensors, t, robot, phi, last) -> dict:
    meas = sensors.measure(*robot, phi, last)
    v, w, info, ref = loop.command(t, meas)
    dx, dy = info.x_n - ref.x, info.y_n - ref.y
    c, s = math.cos(ref.theta), math.sin(ref.theta)
    out = {"v_cmd": v, "w_cmd": w, "x_e": info.x_e, "y_e": info.y_e, "theta_e": info.theta_e,
           "x_d": ref.x, "y_d": ref.y, "theta_d": ref.theta, "v_d": ref.v, "w_d": ref.w,
           "e_lon": c * dx + s * dy, "e_lat": -s * dx + c * dy,
           "e_theta": wrap_scalar(info.theta_n - ref.theta),
           "mode": MODES[info.mode], "direction": ref.direction}
    out.update({f"phi_meas[{i + 1}]": float(a) for i, a in enumerate(meas.phi)})
    return out


@pytest.mark.parametrize("seed", range(6))
def test_fmu_command_equals_the_python_controller(controller_sim, seed):
    """Random reference (pushes, pulls, cusps), chain model, gains, limits, sensor model and
    states: every output of the FMU equals the Python controller's to 1e-12, step after step
    (the rate limits and the backlash carry over)."""
    rng = np.random.default_rng(1000 + seed)
    n = int(rng.integers(1, 5))
    config, sensor = _random_config(rng, n)
    reference = _random_reference(rng)
    sim = controller_sim(n, table_of(reference, config.geometry))
    pulls = reference.pull_intervals()
    compared, modes = 0, set()
    for case in range(8):
        # start times anywhere: before t0, pushing, pulling, in a dwell, after the goal
        if pulls and case % 2:
            a, b = pulls[int(rng.integers(len(pulls)))]
            t = float(rng.uniform(a, b - 0.3))
        elif case % 4 == 0:  # while pushing
            times = rng.uniform(reference.t0, reference.t_end - 0.3, 200)
            pushing = times[reference.direction_at(times + 0.3) == PUSH]
            t = float(pushing[0] if pushing.size else times[0])
        else:
            t = float(rng.uniform(reference.t0 - 1.0, reference.t_end + 1.0))
        h = float(rng.choice([0.005, 0.01, 0.02]))
        v_start, w_start = float(rng.uniform(-0.1, 0.1)), float(rng.uniform(-0.1, 0.1))
        dt_start = float(rng.choice([0.0, h]))
        sim.fmu.reset()
        sim.initialize(_parameters(config, sensor, v_start, w_start, dt_start), start_time=t)
        ctrl = BackwardController(config)
        ctrl.reset(v_start, w_start, t - dt_start if dt_start > 0 else None)
        loop = TrackingLoop(ctrl, reference)
        sensors = Sensors(SensorConfig(
            n_joints=n, joint_bias=sensor["bias"], joint_quantization=sensor["quantization"],
            joint_backlash=sensor["backlash"],
            localize="last_trailer" if sensor["last"] else "robot"))
        for _ in range(12):
            robot, phi, last = _random_state(rng, reference, config.geometry, t)
            inputs = {"x0": robot[0], "y0": robot[1], "theta0": robot[2], "x_last": last[0],
                      "y_last": last[1], "theta_last": last[2]}
            inputs.update({f"phi[{i + 1}]": float(a) for i, a in enumerate(phi)})
            sim.set(inputs)
            expected = _python_outputs(loop, sensors, t, robot, phi, last)
            got = dict(zip(expected, sim.get(list(expected)), strict=True))
            for name, value in expected.items():
                assert got[name] == pytest.approx(value, abs=1e-12, rel=1e-12), (
                    f"{name} at t = {t} (case {case})")
            compared += 1
            modes.add(expected["mode"])
            sim.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
            t = t + h
    assert compared == 96
    laws = {MODES["push" if seg.direction == PUSH else "pull"] for seg in reference.segments}
    assert modes >= laws, modes  # both laws were exercised, not only rest


def test_outputs_follow_the_inputs_and_the_step_commits_the_first_read(controller_sim):
    """Outputs at t are recomputed when the inputs change at t (a Gauss-Seidel master reads
    them after setting the inputs), and the step commits the first command read at t (what a
    Jacobi master forwards): the rate limits continue from it."""
    sim = controller_sim(1, STRAIGHT)
    sim.initialize({"acc_max": 0.2, "alpha_max": 0.2, "dt_start": 0.0})  # first: not limited
    sim.set({"x0": 1.04, "y0": 0.3, "theta0": math.pi, "phi[1]": 0.0})
    first = sim.get(["v_cmd", "w_cmd", "e_lat"])
    sim.set({"y0": -0.3})
    second = sim.get(["v_cmd", "w_cmd", "e_lat"])
    assert second[2] == pytest.approx(-first[2]) and second[2] != first[2]
    assert second[1] == pytest.approx(-first[1]) and abs(first[1]) > 0.003
    sim.fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.005)
    sim.set({"y0": -0.3})
    third = sim.get(["v_cmd", "w_cmd"])
    # the yaw rate wants to go on turning toward -first: rate limited from the committed first
    # command, at most alpha_max * 0.005 away from it (and far from the second)
    assert abs(third[1] - first[1]) <= 0.2 * 0.005 + 1e-15
    assert abs(third[1] - second[1]) > 0.005


# ------------------------------------------------------------------ guards

@pytest.mark.parametrize("name, value", [("x0", math.nan), ("phi[2]", math.inf),
                                         ("theta_last", -math.inf)])
def test_non_finite_inputs_are_refused(controller_sim, name, value):
    sim = controller_sim(2, STRAIGHT)
    sim.initialize()
    with pytest.raises(FMICallException):
        sim.set({name: value})
    assert any(f"input {name} = " in m and "must be finite" in m for _, _, m in sim.messages)
    with pytest.raises(FMICallException):  # the instance is in the error state
        sim.step(0.005)
    assert any("not allowed in mode Error" in m for _, _, m in sim.messages)


@pytest.mark.parametrize("name, value, text", [
    ("k_y", 0.0, "k_y = 0: allowed 0.001 to 1000"),
    ("front[1]", 0.01, "front[1] = 0.01: allowed 0.05 to 10 m"),
    ("acc_max", -1.0, "acc_max = -1: allowed >= 0 m/s2 (0 switches the rate limit off)"),
])
def test_parameters_out_of_range_are_refused(controller_sim, name, value, text):
    sim = controller_sim(1, STRAIGHT)
    with pytest.raises(FMICallException):
        sim.initialize({name: value})
    assert any(text in m for _, _, m in sim.messages), sim.messages


def test_parameters_are_fixed_after_initialization_and_outputs_read_only(controller_sim):
    sim = controller_sim(1, STRAIGHT)
    sim.initialize()
    with pytest.raises(FMICallException):
        sim.set({"k_x": 2.0})
    assert any("parameter k_x cannot be set in mode StepComplete" in m
               for _, _, m in sim.messages)
    sim2 = controller_sim(1, STRAIGHT)
    with pytest.raises(FMICallException):
        sim2.set({"v_cmd": 0.0})


def test_a_communication_point_that_skips_is_refused(controller_sim):
    sim = controller_sim(1, STRAIGHT)
    sim.initialize()
    with pytest.raises(FMICallException):
        sim.fmu.doStep(currentCommunicationPoint=0.5, communicationStepSize=0.005)
    assert any("differs from the FMU's time" in m for _, _, m in sim.messages)


# ------------------------------------------------------------------ resources

def _instantiate_at(unzipdir: Path, md, uri: str, messages: list):
    """fmi2Instantiate with this resource location; returns the FMU2Slave or None."""
    from fmpy.fmi2 import (
        FMU2Slave,
        fmi2CallbackFunctions,
        fmi2CallbackLoggerTYPE,
        fmi2CoSimulation,
    )
    from fmpy.logging import addLoggerProxy

    def log(_env, _name, status, _category, message):
        messages.append(message.decode("utf-8", "replace"))

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(log)
    addLoggerProxy(byref(callbacks))  # formats the message's printf arguments
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=str(unzipdir),
                    modelIdentifier="BackwardController", instanceName="c")
    fmu._keep = callbacks
    fmu.component = fmu.fmi2Instantiate(b"c", fmi2CoSimulation, md.guid.encode(), uri.encode(),
                                        byref(callbacks), 0, 0)
    if not fmu.component:
        fmu.freeLibrary()
        return None
    return fmu


@pytest.fixture
def moved_resources(tmp_path):
    """A controller FMU whose resources live in a folder with a space and non-ASCII letters."""
    path = build_controller_fmu(1, STRAIGHT, tmp_path / "c.fmu")
    unzipdir = Path(extract(str(path), unzipdir=str(tmp_path / "unzipped")))
    odd = tmp_path / "mission data é%"
    shutil.copytree(unzipdir / "resources", odd)
    return unzipdir, read_model_description(str(path)), odd


@pytest.mark.parametrize("form", ["as_uri", "one_slash", "localhost", "four_slashes",
                                  "trailing_slash"])
def test_resource_location_forms(moved_resources, form):
    unzipdir, md, folder = moved_resources
    encoded = folder.as_uri()  # file:///.../mission%20data%20%C3%A9%25
    assert "%20" in encoded and "%C3%A9" in encoded and "%25" in encoded
    path_part = encoded[len("file://"):]
    uri = {"as_uri": encoded, "one_slash": "file:" + path_part,
           "localhost": "file://localhost" + path_part, "four_slashes": "file:///" + path_part,
           "trailing_slash": encoded + "/"}[form]
    messages = []
    fmu = _instantiate_at(unzipdir, md, uri, messages)
    assert fmu is not None, messages
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    assert fmu.getReal([vr["t_end"]])[0] == pytest.approx(2.0 / 0.08)
    fmu.freeInstance()


@pytest.mark.parametrize("uri, text", [
    ("http://example.org/resources", "only file: URIs"),
    ("file://otherhost/tmp/resources", "another host"),
    ("file:///tmp/bad%2", "bad percent-encoding"),
    ("file:///no/such/folder", "cannot open the mission table"),
])
def test_bad_resource_locations_are_refused(moved_resources, uri, text):
    unzipdir, md, _ = moved_resources
    messages = []
    assert _instantiate_at(unzipdir, md, uri, messages) is None
    assert any(text in m for m in messages), messages


@pytest.mark.parametrize("edit, text", [
    (lambda s: s.replace("speed 0.08", "speed 0.08x"), "speed = '0.08x': must be a finite"),
    (lambda s: s.replace("line 2.0", "lane 2.0"), "segment kind = 'lane'"),
    (lambda s: s.replace("segments 1", "segments 2"), "segment kind = 'leader_runs'"),
    (lambda s: s.replace("pushtrain-reference 1", "pushtrain-reference 7"), "table format 7"),
    (lambda s: s + "extra\n", "'extra' after the last leader run"),
    (lambda s: s.replace("line 2.0 0.0", "line 2.0 0.5"), "a line has curvature 0"),
])
def test_bad_tables_are_refused_with_the_line(moved_resources, edit, text):
    unzipdir, md, folder = moved_resources
    table = folder / "reference.txt"
    table.write_text(edit(table.read_text()))
    messages = []
    assert _instantiate_at(unzipdir, md, folder.as_uri(), messages) is None
    assert any(text in m and "reference.txt:" in m for m in messages), messages


def test_table_round_trips_every_double():
    rng = np.random.default_rng(5)
    values = rng.normal(size=6) * 10.0 ** rng.integers(-12, 6, 6)
    table = ControllerTable((values[0], values[1], values[2]),
                            (Segment("arc", 1.5, values[3], PULL, None),), 0.08, 0.0,
                            leader_runs=(np.column_stack([np.arange(3.0)] + [values[:3]] * 5),))
    text = render_table(table)
    numbers = [float(tok) for line in text.splitlines() if not line.startswith("#")
               for tok in line.split()[1:] if tok[0] in "-0123456789"]
    for v in values[:4]:
        assert float(v) in numbers  # repr() reads back exactly


def test_malformed_tables_are_refused_in_python():
    with pytest.raises(FmuInputError, match="at least one segment"):
        ControllerTable((0.0, 0.0, 0.0), (), 0.08, 1.0)
    with pytest.raises(FmuInputError, match="leader run 0"):
        ControllerTable((0.0, 0.0, 0.0), (Segment("line", 1.0, 0.0, 1),), 0.08, 1.0,
                        leader_runs=(np.zeros((1, 6)),))
