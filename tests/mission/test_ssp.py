"""``pushtrain export-ssp``: the closed loop as an SSP 1.0 package, run by other tools.

The package validates against the SSP 1.0 schema (the Modelica Association's normative XSDs,
BSD-2-Clause, as shipped with fmpy), holds every connection and the scenario's parameters, and
runs in libcosim (OSP). The timing equivalence documented in ``pushtrain.mission.ssp`` is held
exactly: libcosim's fixed-step (Jacobi) run equals pushtrain's loop with a one-step measurement
delay, and a Gauss-Seidel loop over the two FMUs equals pushtrain's own master; libcosim's run
equals ``plan-and-run``'s trajectory to 1 mm.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from reference.controller import BackwardController

from pushtrain.cli.main import cli
from pushtrain.core.sensors import Sensors
from pushtrain.core.tracking import TrackingLoop
from pushtrain.mission.runner import (
    controller_of,
    initial_of,
    run_scenario,
    scripted_reference,
    sensors_of,
)
from pushtrain.mission.scenario import load_scenario, parse_scenario
from pushtrain.mission.ssp import (
    CONTROLLER,
    NS,
    PLANT,
    controller_parameters,
    export_ssp,
    plant_parameters,
)

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
MM = 1e-3

# A short scripted mission with both laws: a pull (the robot leads along the pull guide), a cusp,
# then a push along a line, an arc and a line; the last trailer localized directly, a biased and
# quantized joint.
SHORT = {
    "name": "short_loop", "mission": {"kind": "scripted"}, "train": {"n": 3},
    "start": {"x": 0.0, "y": 0.0, "theta_deg": 180.0, "lateral_offset": 0.05},
    "reference": {"speed": 0.08, "cusp_dwell": 1.0, "segments": [
        {"kind": "line", "length": 0.8, "direction": "pull"},
        {"kind": "line", "length": 0.5},
        {"kind": "arc", "length": 0.8, "radius": 2.0, "turn": "left"},
        {"kind": "line", "length": 0.6},
    ]},
    "controller": {"acc_max": 0.2, "alpha_max_deg": 10.0},
    "sensors": {"localize": "last_trailer", "joint_bias_deg": [0.0, 2.0, 0.0],
                "joint_quantization_deg": 0.05},
    "sim": {"settle_time": 8.0},
}


def _schema(name: str):
    from lxml import etree

    fmpy = pytest.importorskip("fmpy")
    return etree.XMLSchema(file=str(Path(fmpy.__file__).parent / "ssp" / "schema" / name))


@pytest.fixture(scope="module")
def short(tmp_path_factory):
    """The short mission, its reference and its exported package."""
    sc = parse_scenario(SHORT)
    ref = scripted_reference(sc)
    path = tmp_path_factory.mktemp("ssp") / "short.ssp"
    done = export_ssp(sc, ref, path, ospconfig=True)
    return sc, ref, done


def _members(path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as zf:
        return {name: zf.read(name) for name in zf.namelist()}


# ------------------------------------------------------------------ the package

def test_package_validates_against_the_ssp_schema(short):
    from lxml import etree

    _, _, done = short
    members = _members(done.path)
    assert {"SystemStructure.ssd", "resources/TrailerTrain.fmu",
            "resources/BackwardController.fmu", "resources/train.ssv",
            "resources/controller.ssv", "OspSystemStructure.xml"} == set(members)
    ssd = _schema("SystemStructureDescription.xsd")
    assert ssd.validate(etree.fromstring(members["SystemStructure.ssd"])), ssd.error_log
    ssv = _schema("SystemStructureParameterValues.xsd")
    for name in ("resources/train.ssv", "resources/controller.ssv"):
        assert ssv.validate(etree.fromstring(members[name])), (name, ssv.error_log)


def test_the_schema_check_would_catch_a_broken_package(short):
    from lxml import etree

    _, _, done = short
    root = etree.fromstring(_members(done.path)["SystemStructure.ssd"])
    del root.attrib["version"]  # required by SSP 1.0
    assert not _schema("SystemStructureDescription.xsd").validate(root)


def test_every_connection_between_the_components(short):
    sc, _, done = short
    n = sc.train.n
    root = ET.fromstring(_members(done.path)["SystemStructure.ssd"])
    found = {(c.get("startElement"), c.get("startConnector"), c.get("endElement"),
              c.get("endConnector")) for c in root.iter(f"{{{NS['ssd']}}}Connection")}
    expected = {(PLANT, "x[0]", CONTROLLER, "x0"), (PLANT, "y[0]", CONTROLLER, "y0"),
                (PLANT, "theta[0]", CONTROLLER, "theta0"),
                (PLANT, f"x[{n}]", CONTROLLER, "x_last"), (PLANT, f"y[{n}]", CONTROLLER, "y_last"),
                (PLANT, f"theta[{n}]", CONTROLLER, "theta_last"),
                (CONTROLLER, "v_cmd", PLANT, "v_cmd"), (CONTROLLER, "w_cmd", PLANT, "w_cmd")}
    expected |= {(PLANT, f"phi[{i}]", CONTROLLER, f"phi[{i}]") for i in range(1, n + 1)}
    assert found == expected
    # each end is a declared connector of the right kind, and exists in its FMU
    from fmpy import read_model_description

    declared = {}
    for comp in root.iter(f"{{{NS['ssd']}}}Component"):
        declared[comp.get("name")] = {c.get("name"): c.get("kind")
                                      for c in comp.iter(f"{{{NS['ssd']}}}Connector")}
    members = _members(done.path)
    for comp, fmu in ((PLANT, "TrailerTrain"), (CONTROLLER, "BackwardController")):
        fmu_path = done.path.parent / f"{fmu}.fmu"
        fmu_path.write_bytes(members[f"resources/{fmu}.fmu"])
        md = {v.name: v.causality for v in read_model_description(str(fmu_path)).modelVariables}
        for name, kind in declared[comp].items():
            assert md[name] == kind, (comp, name)
    for a, b, c, d in found:
        assert declared[a][b] == "output" and declared[c][d] == "input"


def test_parameters_and_experiment_are_the_scenario_s(short):
    sc, ref, done = short
    members = _members(done.path)

    def values(name):
        root = ET.fromstring(members[name])
        out = {}
        for p in root.iter(f"{{{NS['ssv']}}}Parameter"):
            (typed,) = list(p)
            out[p.get("name")] = typed.get("value")
        return out

    train, ctrl = values("resources/train.ssv"), values("resources/controller.ssv")
    initial = initial_of(sc, ref)
    assert {k: float(v) for k, v in train.items()} == pytest.approx(
        {k: float(v) for k, v in plant_parameters(sc, initial).items()}, abs=0)
    assert float(train["theta_start[0]"]) == initial.theta[0]  # the chain starts on the path
    assert float(ctrl["joint_bias[2]"]) == pytest.approx(math.radians(2.0), abs=1e-17)
    assert float(ctrl["acc_max"]) == 0.2 and ctrl["measure_last_pose"] == "true"
    assert float(ctrl["dt_start"]) == sc.sim.step
    root = ET.fromstring(members["SystemStructure.ssd"])
    experiment = root.find(f"{{{NS['ssd']}}}DefaultExperiment")
    horizon = sc.sim.step * math.ceil((ref.t_end - ref.t0 + sc.sim.settle_time) / sc.sim.step
                                      - 1e-9)
    assert float(experiment.get("stopTime")) == pytest.approx(horizon, abs=1e-12)
    step = experiment.find(f".//{{{NS['osp']}}}FixedStepAlgorithm")
    assert float(step.get("baseStepSize")) == sc.sim.step


# ------------------------------------------------------------------ the CLI

def _cli(*args):
    return CliRunner().invoke(cli, list(args))


def test_cli_exports_a_scripted_mission(tmp_path):
    out = tmp_path / "circle.ssp"
    result = _cli("export-ssp", str(EXAMPLES / "circle.toml"), "-o", str(out))
    assert result.exit_code == 0, result.output
    assert "11 connections" in result.output and zipfile.is_zipfile(out)
    # nothing half-written beside it
    assert [p.name for p in tmp_path.iterdir()] == ["circle.ssp"]


@pytest.mark.parametrize("args, text", [
    (["rotation_slip.toml", "-o", "{tmp}/r.ssp"],
     "mission.kind = 'rotation' has no plan and no scripted reference"),
    (["circle.toml", "-o", "{tmp}/missing/c.ssp"], "the folder"),
    (["circle.toml", "-o", "{tmp}"], "is a directory"),
    (["circle.toml", "-o", "/proc/c.ssp"], "cannot be written"),
    (["slip_governor.toml", "-o", "{tmp}/g.ssp"], "controller.governor"),
])
def test_cli_bad_input_exits_2(tmp_path, args, text):
    args = [a.format(tmp=tmp_path) for a in args]
    args[0] = str(EXAMPLES / args[0])
    result = _cli("export-ssp", *args)
    assert result.exit_code == 2, result.output
    assert text in result.output
    assert "Traceback" not in result.output
    assert not list(tmp_path.glob("*.ssp"))


def test_cli_reports_what_is_not_exported(tmp_path):
    result = _cli("export-ssp", str(EXAMPLES / "straight_push.toml"), "-o",
                  str(tmp_path / "s.ssp"))
    assert result.exit_code == 0, result.output
    assert "not exported: events: 1 timed disturbance(s)" in result.output


# ------------------------------------------------------------------ running it elsewhere

def libcosim_run(path: Path, n: int, steps: int, osp: bool = False) -> dict:
    """Step the package in libcosim; the last trailer's pose and done after every step."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.ERROR)
    execution = (CosimExecution.from_osp_config_file(str(path)) if osp
                 else CosimExecution.from_ssp_file(str(path)))
    observer = CosimObserver.create_last_value()
    assert execution.add_observer(observer=observer)
    train = execution.slave_index_from_instance_name(PLANT)
    ctrl = execution.slave_index_from_instance_name(CONTROLLER)
    ref = {}
    for index in (train, ctrl):
        ref[index] = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
    pose = [ref[train][f"{b}[{n}]"] for b in ("x", "y", "theta")]
    rows, done = [], []
    for _ in range(steps):
        assert execution.step(), "libcosim step failed"
        rows.append(observer.last_real_values(train, pose))
        done.append(observer.last_boolean_values(ctrl, [ref[ctrl]["done"]])[0])
    rows = np.array(rows)
    return {"x": rows[:, 0], "y": rows[:, 1], "theta": rows[:, 2], "done": np.array(done)}


def delayed_loop(sc, ref, plant_sim, steps: int, first=None) -> dict:
    """pushtrain's loop with the controller one measurement behind (a Jacobi master): the
    command over [t_k, t_k+1] is the law at t_k on the measurement at t_k-1; at k = 0 on the
    measurement at t_0 (propagated in initialization, as libcosim does) or on ``first`` (the
    controller's input start values, when the master does not propagate)."""
    n, h = sc.train.n, sc.sim.step
    initial = initial_of(sc, ref)
    plant_sim.initialize(plant_parameters(sc, initial))
    ctrl = BackwardController(controller_of(sc))
    ctrl.reset(initial.v0, initial.w0, ref.t0 - h)
    loop = TrackingLoop(ctrl, ref)
    sensors = Sensors(sensors_of(sc))
    names = ["x[0]", "y[0]", "theta[0]", *[f"phi[{i}]" for i in range(1, n + 1)],
             f"x[{n}]", f"y[{n}]", f"theta[{n}]"]
    previous = plant_sim.get(names)
    out = []
    for k in range(steps):
        t = ref.t0 + k * h
        y = plant_sim.get(names)
        seen = previous if k > 0 else (y if first is None else first)
        meas = sensors.measure(*seen[:3], np.array(seen[3:3 + n]), tuple(seen[3 + n:]))
        v, w, _, _ = loop.command(t, meas)
        plant_sim.set({"v_cmd": v, "w_cmd": w})
        plant_sim.step(h)
        previous = y
        out.append(plant_sim.get(names[-3:]))
    out = np.array(out)
    return {"x": out[:, 0], "y": out[:, 1], "theta": out[:, 2]}


def _distance(a: dict, xs, ys) -> np.ndarray:
    return np.hypot(a["x"] - xs, a["y"] - ys)


@pytest.fixture(scope="module")
def short_master(short):
    """pushtrain's own run of the short mission (perfect sensors but for the exported bias and
    quantization: what the package holds)."""
    sc, ref, _ = short
    return run_scenario(sc, reference=ref)


def test_libcosim_equals_the_loop_with_a_one_step_measurement_delay(short, built_fmu_sim):
    pytest.importorskip("libcosimpy")
    sc, ref, done = short
    steps = 2000
    tool = libcosim_run(done.path, sc.train.n, steps)
    emulated = delayed_loop(sc, ref, built_fmu_sim(sc.train.n), steps)
    for key in ("x", "y", "theta"):
        np.testing.assert_allclose(tool[key], emulated[key], rtol=0, atol=1e-9)


def test_libcosim_reaches_the_goal_within_1_mm_of_pushtrain(short, short_master):
    pytest.importorskip("libcosimpy")
    sc, _, done = short
    data = short_master.data
    assert short_master.status == "goal_reached"
    n, steps = sc.train.n, len(data) - 1
    tool = libcosim_run(done.path, n, steps)
    gap = _distance(tool, data[f"x{n}"][1:], data[f"y{n}"][1:])
    assert gap.max() < 1 * MM, gap.max()
    assert gap.max() > 1e-7  # the delay is real: this is not the same loop
    assert tool["done"][-1]  # the controller's own goal test agrees at the master's stop


def test_a_gauss_seidel_master_over_the_fmus_is_pushtrain_s_loop(short, short_master, tmp_path):
    """Plant outputs at t_k -> controller inputs -> controller outputs -> plant inputs -> step
    both: the controller FMU then reproduces the master's trajectory (C and Python law agree to
    rounding)."""
    from conftest import TrailerSim
    from fmpy import extract, read_model_description

    sc, ref, done = short
    n, h = sc.train.n, sc.sim.step
    members = _members(done.path)
    sims = {}
    for name, fmu in ((PLANT, "TrailerTrain"), (CONTROLLER, "BackwardController")):
        path = tmp_path / f"{fmu}.fmu"
        path.write_bytes(members[f"resources/{fmu}.fmu"])
        unzipdir = extract(str(path), unzipdir=str(tmp_path / fmu))
        sims[name] = TrailerSim(unzipdir, read_model_description(str(path)), instance_name=name)
    plant, ctrl = sims[PLANT], sims[CONTROLLER]
    initial = initial_of(sc, ref)
    try:
        plant.initialize(plant_parameters(sc, initial), start_time=ref.t0)
        ctrl.initialize(controller_parameters(sc, initial, h), start_time=ref.t0)
        links = [(f"x[{n}]", "x_last"), (f"y[{n}]", "y_last"), (f"theta[{n}]", "theta_last"),
                 ("x[0]", "x0"), ("y[0]", "y0"), ("theta[0]", "theta0")]
        links += [(f"phi[{i}]", f"phi[{i}]") for i in range(1, n + 1)]
        data = short_master.data
        xs, ys = [], []
        for _ in range(len(data) - 1):
            ctrl.set(dict(zip([b for _, b in links], plant.get([a for a, _ in links]),
                              strict=True)))
            v, w = ctrl.get(["v_cmd", "w_cmd"])
            plant.set({"v_cmd": v, "w_cmd": w})
            plant.step(h)
            ctrl.step(h)
            xs.append(plant.real(f"x[{n}]"))
            ys.append(plant.real(f"y[{n}]"))
        gap = np.hypot(np.array(xs) - data[f"x{n}"][1:], np.array(ys) - data[f"y{n}"][1:])
        assert gap.max() < 1e-9, gap.max()
        assert ctrl.get(["done"])[0]
    finally:
        plant.free()
        ctrl.free()


def test_libcosim_runs_the_osp_config_like_the_ssp(short, tmp_path):
    pytest.importorskip("libcosimpy")
    sc, _, done = short
    with zipfile.ZipFile(done.path) as zf:
        zf.extractall(tmp_path)
    steps = 400
    via_osp = libcosim_run(tmp_path / "OspSystemStructure.xml", sc.train.n, steps, osp=True)
    via_ssp = libcosim_run(done.path, sc.train.n, steps)
    for key in ("x", "y", "theta"):
        np.testing.assert_array_equal(via_osp[key], via_ssp[key])


@pytest.mark.slow
@pytest.mark.parametrize("example", ["l_corridor", "bay"])
def test_planned_missions_in_libcosim_match_plan_and_run(tmp_path, example):
    """The exported planned missions (the bay pulls, then pushes into the bay) run to the goal
    in libcosim, and the last trailer stays within 1 mm of pushtrain's own plan-and-run."""
    pytest.importorskip("libcosimpy")
    from pushtrain.mission.runner import plan_path

    sc = load_scenario(EXAMPLES / f"{example}.toml")
    ref = plan_path(sc).to_reference(speed=sc.planner.speed, cusp_dwell=sc.planner.cusp_dwell)
    master = run_scenario(sc, reference=ref)
    assert master.status == "goal_reached"
    done = export_ssp(sc, ref, tmp_path / f"{example}.ssp")
    n, data = sc.train.n, master.data
    tool = libcosim_run(done.path, n, len(data) - 1)
    gap = _distance(tool, data[f"x{n}"][1:], data[f"y{n}"][1:])
    assert gap.max() < 1 * MM, gap.max()
    assert tool["done"][-1]
    if example == "bay":
        assert ref.pull_intervals()  # the pull guide's table was exercised


def _load_tbb() -> None:
    """ecospy's native library needs libtbb.so.12 (Debian's libtbb12); the test extras install
    the ``tbb`` wheel, which puts it in the environment's lib folder, off the loader's path:
    load it first, globally, so that ecospy's library finds it."""
    import ctypes
    import sys

    lib = Path(sys.prefix) / "lib" / "libtbb.so.12"
    if lib.exists():
        ctypes.CDLL(str(lib), mode=ctypes.RTLD_GLOBAL)


def ecos_run(path: Path, n: int, steps: int, step: float) -> dict:
    """Step the package in ecos (ecospy); the last trailer's pose after every step."""
    _load_tbb()
    try:
        from ecospy import EcosLib, EcosSimulation
    except (ImportError, OSError) as exc:  # not installed, or its libtbb12 missing
        pytest.skip(f"ecospy not usable: {exc}")
    EcosLib.set_log_level("warn")
    rows = []
    with EcosSimulation(step_size=step, ssp_path=str(path)) as sim:
        assert sim.init(parameter_set="mission")
        for _ in range(steps):
            sim.step()
            rows.append([sim.get_real(f"{PLANT}::{b}[{n}]") for b in ("x", "y", "theta")])
        done = sim.get_bool(f"{CONTROLLER}::done")
    rows = np.array(rows)
    return {"x": rows[:, 0], "y": rows[:, 1], "theta": rows[:, 2], "done": done}


def test_ecos_runs_the_package_like_libcosim(short, short_master, built_fmu_sim):
    """ecos's fixed-step master is a Jacobi master too: the same one-step measurement delay,
    and within 1 mm of pushtrain's run."""
    sc, ref, done = short
    data = short_master.data
    n, steps = sc.train.n, len(data) - 1
    tool = ecos_run(done.path, n, steps, sc.sim.step)
    emulated = delayed_loop(sc, ref, built_fmu_sim(n), 2000)
    for key in ("x", "y", "theta"):
        np.testing.assert_allclose(tool[key][:2000], emulated[key], rtol=0, atol=1e-9)
    gap = _distance(tool, data[f"x{n}"][1:], data[f"y{n}"][1:])
    assert gap.max() < 1 * MM, gap.max()
    assert tool["done"]


def test_fmpy_runs_the_package_with_a_parameter_set_by_hand(short, short_master):
    """fmpy's SSP loop (what it cannot do: apply the SSD's parameter bindings, read Booleans
    from strings, propagate initial values) reaches the goal a little further off."""
    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import Parameter, ParameterSet, read_ssv

    sc, _, done = short
    parameters = ParameterSet(name="mission")
    for comp in (PLANT, CONTROLLER):
        for p in read_ssv(str(done.path), resource=f"resources/{comp}.ssv").parameters:
            value = (1.0 if p.value == "true" else 0.0) if p.type == "Boolean" else p.value
            parameters.parameters.append(Parameter(name=f"{comp}.{p.name}", type=p.type,
                                                   value=value))
    data = short_master.data
    n, steps = sc.train.n, len(data) - 1
    result = simulate_ssp(str(done.path), stop_time=steps * sc.sim.step - 1e-9,
                          step_size=sc.sim.step, parameter_set=parameters)
    assert len(result) == steps
    gap = np.hypot(result[f"{PLANT}.x[{n}]"] - data[f"x{n}"][1:],
                   result[f"{PLANT}.y[{n}]"] - data[f"y{n}"][1:])
    assert gap.max() < 3 * MM, gap.max()
    assert result[f"{CONTROLLER}.done"][-1]


def _readme_block(after: str) -> str:
    text = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    start = text.index("```python", text.index(after)) + len("```python")
    return text[start:text.index("```", start)]


@pytest.mark.parametrize("tool, heading", [("libcosimpy", "With libcosim (`pip install"),
                                           ("ecospy", "With ecos (`pip install")])
def test_readme_snippets_run_the_package(short, tmp_path, tool, heading):
    """The README's snippets, each alone in a fresh Python as a user pastes it (so the ecos one
    must load libtbb itself), run an exported package to ``done`` (and plot it), quietly: no
    debug log (libcosim printed 68 lines of it)."""
    import subprocess
    import sys

    _load_tbb()
    try:
        __import__(tool)
    except (ImportError, OSError) as exc:
        pytest.skip(f"{tool} not usable: {exc}")
    _, _, done = short
    (tmp_path / "mission.ssp").write_bytes(done.path.read_bytes())
    code = "import matplotlib\nmatplotlib.use('Agg')\n" + _readme_block(heading)
    if tool == "libcosimpy":
        code += "\nprint('points', len(xs))\n"
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert len(proc.stderr.splitlines()) <= 2, proc.stderr[-3000:]
    if tool == "libcosimpy":
        assert (tmp_path / "mission.png").stat().st_size > 1000
        label, points = proc.stdout.split()
        assert int(points) < 10_000  # it stopped on done, not on the loop's bound
    else:  # it printed the time at done, and the last trailer's position
        t, x, y = (float(v) for v in proc.stdout.split())
        assert t < 100.0 and math.isfinite(x) and math.isfinite(y)


@pytest.mark.parametrize("settle", [0.0, 0.0023, 1.0, 2.0049])
def test_the_package_runs_at_least_to_the_end_of_the_reference_in_whole_steps(settle):
    """SSP's stop time: the reference's end plus the settle time, rounded UP to whole steps
    (never cutting the run short of what pushtrain's own master runs)."""
    from pushtrain.mission.ssp import horizon_of

    sc = parse_scenario({**SHORT, "sim": {"settle_time": settle}}, "short.toml")
    reference = scripted_reference(sc)
    step = sc.sim.step
    want = float(reference.t_end) - float(reference.t0) + settle
    got = horizon_of(sc, reference)
    assert want - 1e-9 <= got < want + step
    assert abs(got / step - round(got / step)) < 1e-9
