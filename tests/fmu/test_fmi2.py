"""FMI 2.0 conformance of the TrailerTrain FMU: validation, importers, instances, state, steps."""

from __future__ import annotations

import re
import shutil
import subprocess
import zipfile

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from pushtrain.fmu.variables import variables_for

N_DEFAULT = 3

# Every function of the FMI 2.0 Co-Simulation interface (common + CS-specific).
FMI2_CS_FUNCTIONS = {
    "fmi2GetTypesPlatform", "fmi2GetVersion", "fmi2SetDebugLogging", "fmi2Instantiate",
    "fmi2FreeInstance", "fmi2SetupExperiment", "fmi2EnterInitializationMode",
    "fmi2ExitInitializationMode", "fmi2Terminate", "fmi2Reset", "fmi2GetReal", "fmi2GetInteger",
    "fmi2GetBoolean", "fmi2GetString", "fmi2SetReal", "fmi2SetInteger", "fmi2SetBoolean",
    "fmi2SetString", "fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate",
    "fmi2SerializedFMUstateSize", "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate",
    "fmi2GetDirectionalDerivative", "fmi2SetRealInputDerivatives",
    "fmi2GetRealOutputDerivatives", "fmi2DoStep", "fmi2CancelStep", "fmi2GetStatus",
    "fmi2GetRealStatus", "fmi2GetIntegerStatus", "fmi2GetBooleanStatus", "fmi2GetStringStatus",
}

OUTPUT_BLOCKS = ("x", "y", "theta", "phi", "v", "w", "F_lat", "hitch_fx", "hitch_fy")


def xml_start(var):
    """The XML start value of an fmpy ModelVariable, parsed by its type (None if absent)."""
    if var.start is None:
        return None
    if var.type == "Real":
        return float(var.start)
    if var.type == "Integer":
        return int(var.start)
    if var.type == "Boolean":
        return var.start.strip().lower() in ("true", "1")
    return var.start


def record(sim, names):
    """Current values of ``names`` as a float array."""
    return np.array(sim.get(names), dtype=float)


def output_names(sim):
    """Every Real output (the recorded trajectory)."""
    return [v.name for v in sim.md.modelVariables
            if v.causality == "output" and v.type == "Real"]


# -- static checks ------------------------------------------------------------------------------
@pytest.mark.parametrize("n_trailers", [1, N_DEFAULT])
def test_validate_fmu_reports_no_problems(built_fmu, n_trailers):
    problems = validate_fmu(str(built_fmu(n_trailers)))
    assert problems == []


def test_fmu_archive_is_self_contained(built_fmu):
    with zipfile.ZipFile(built_fmu(N_DEFAULT)) as archive:
        names = set(archive.namelist())
    assert "modelDescription.xml" in names
    assert "binaries/linux64/TrailerTrain.so" in names
    assert any(name.startswith("sources/") and name.endswith(".c") for name in names)


@pytest.mark.parametrize("n_trailers", [1, N_DEFAULT, 7])
def test_model_description_matches_variable_table(built_fmu, n_trailers):
    md = read_model_description(str(built_fmu(n_trailers)))
    assert md.coSimulation is not None
    assert md.coSimulation.modelIdentifier == "TrailerTrain"
    xml = {v.name: v for v in md.modelVariables}
    table = {v.name: v for v in variables_for(n_trailers)}
    assert sorted(xml) == sorted(table)
    refs = [v.valueReference for v in md.modelVariables]
    assert len(set(refs)) == len(refs), "value references must be unique"
    for name, expected in table.items():
        got = xml[name]
        assert got.valueReference == expected.vr, name
        assert got.type == expected.type, name
        assert got.causality == expected.causality, name
        assert got.variability == expected.variability, name
        if expected.initial is not None:
            assert got.initial == expected.initial, name
        expected_start = n_trailers if name == "n" else expected.start  # n: fixed by the build
        if expected_start is None:
            assert got.start is None, name
        else:
            assert xml_start(got) == expected_start, name
        if expected.unit is not None:
            assert got.unit == expected.unit, name


def test_model_description_names_its_generator_and_utc_date(built_fmu):
    from datetime import datetime

    import pushtrain

    md = read_model_description(str(built_fmu(N_DEFAULT)))
    assert md.generationTool == f"pushtrain {pushtrain.__version__}"
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", md.generationDateAndTime)
    assert datetime.strptime(md.generationDateAndTime, "%Y-%m-%dT%H:%M:%SZ").year >= 2024


def test_generation_date_follows_source_date_epoch_and_not_the_cache_key(monkeypatch):
    from pushtrain.fmu import build, render

    keys = set()
    for epoch, date in ((0, "1970-01-01T00:00:00Z"), (1700000000, "2023-11-14T22:13:20Z")):
        monkeypatch.setenv("SOURCE_DATE_EPOCH", str(epoch))
        xml = render.render_model_description(2, "{guid}").decode()
        assert f'generationDateAndTime="{date}"' in xml
        keys.add(build._fingerprint(2, strict=False))
    assert len(keys) == 1  # a build made on another day is still a cache hit


def test_slip_mode_is_bounded_0_to_1(built_fmu):
    md = read_model_description(str(built_fmu(N_DEFAULT)))
    (slip_mode,) = [v for v in md.modelVariables if v.name == "slip_mode"]
    assert (slip_mode.min, slip_mode.max) == ("0", "1")


@pytest.mark.parametrize("n_trailers", [1, N_DEFAULT])
def test_descriptions_have_no_template_leftovers(built_fmu, n_trailers):
    md = read_model_description(str(built_fmu(n_trailers)))
    leftovers = re.compile(r"(?<![A-Za-z])i(?![A-Za-z])|[{}]|_i\b|i-1|i - 1")
    bad = {v.name: v.description for v in md.modelVariables if leftovers.search(v.description)}
    assert bad == {}
    for var in md.modelVariables:  # and every element names its own body
        match = re.fullmatch(r"(\w+)\[(\d+)\]", var.name)
        if match:
            i = int(match.group(2))
            assert (f"trailer {i}" in var.description or f"[{i}]" in var.description
                    or (i == 0 and "robot" in var.description)), (var.name, var.description)


def test_exported_symbols_are_only_fmi2_functions(built_fmu_unzipped):
    if shutil.which("nm") is None:
        pytest.fail("binutils' nm is required to inspect the FMU's exported symbols")
    unzipdir, _ = built_fmu_unzipped(N_DEFAULT)
    library = unzipdir / "binaries" / "linux64" / "TrailerTrain.so"
    out = subprocess.run(["nm", "-D", "--defined-only", str(library)], check=True,
                         capture_output=True, text=True).stdout
    symbols = {line.split()[-1] for line in out.splitlines() if line.strip()}
    assert symbols, "nm found no exported symbols"
    assert {s for s in symbols if not s.startswith("fmi2")} == set()
    assert FMI2_CS_FUNCTIONS <= symbols, sorted(FMI2_CS_FUNCTIONS - symbols)


# -- importers -----------------------------------------------------------------------------------
def test_simulate_fmu_runs_the_default_experiment(built_fmu):
    path = built_fmu(N_DEFAULT)
    md = read_model_description(str(path))
    assert md.defaultExperiment is not None and md.defaultExperiment.stopTime is not None
    stop = float(md.defaultExperiment.stopTime)
    start = float(md.defaultExperiment.startTime or 0.0)
    result = simulate_fmu(str(path), output=["x[0]", "theta[1]", f"F_lat[{N_DEFAULT}]"])
    assert result["time"][0] == pytest.approx(start)
    assert result["time"][-1] == pytest.approx(stop)
    for name in ("x[0]", "theta[1]", f"F_lat[{N_DEFAULT}]"):
        assert np.all(np.isfinite(result[name])), name


def test_two_interleaved_instances_equal_each_alone(built_fmu_sim):
    """No shared mutable state: interleaved stepping gives bitwise the same trajectories."""
    setups = {
        "a": ({"front[1]": 0.45, "theta_start[2]": 0.2},
              {"v_cmd": -0.1, "w_cmd": 0.05, "push_x": 3.0}),
        "b": ({"rear[0]": 0.61, "mass[3]": 55.0, "theta_start[0]": -0.3},
              {"v_cmd": 0.2, "w_cmd": -0.1, "push_y": -4.0}),
    }
    h, steps = 0.01, 150

    def run_alone(key):
        sim = built_fmu_sim(N_DEFAULT, instance_name=f"alone_{key}")
        sim.initialize(*setups[key])
        names = output_names(sim)
        rows = []
        for _ in range(steps):
            sim.step(h)
            rows.append(record(sim, names))
        sim.free()
        return np.array(rows)

    alone = {key: run_alone(key) for key in setups}

    sims = {key: built_fmu_sim(N_DEFAULT, instance_name=f"both_{key}") for key in setups}
    for key, sim in sims.items():
        sim.initialize(*setups[key])
    names = output_names(sims["a"])
    rows = {key: [] for key in setups}
    for _ in range(steps):
        for key in ("a", "b"):
            sims[key].step(h)
            rows[key].append(record(sims[key], names))
    for key in setups:
        assert np.array_equal(np.array(rows[key]), alone[key]), key
    assert not np.array_equal(alone["a"], alone["b"])


# -- start values -----------------------------------------------------------------------------
def _with_start(sim, causalities):
    return [v for v in sim.md.modelVariables
            if v.start is not None and v.causality in causalities]


def test_values_right_after_instantiate_equal_xml_start(built_fmu_sim):
    """Parameters and inputs hold the XML start values before anything is set.

    FMI 2.0 lets an FMU refuse fmi2GetXXX in the Instantiated state; such a refusal is allowed,
    but values that are returned must be the start values.
    """
    sim = built_fmu_sim(N_DEFAULT)
    variables = _with_start(sim, ("parameter", "input"))
    assert len(variables) > 20
    try:
        values = sim.get([v.name for v in variables])
    except FMICallException:
        pytest.skip("the FMU refuses fmi2GetXXX in the Instantiated state (allowed by FMI 2.0)")
    mismatched = {v.name: (got, xml_start(v)) for v, got in zip(variables, values, strict=True)
                  if got != xml_start(v)}
    assert mismatched == {}


@pytest.mark.parametrize("n_trailers", [1, N_DEFAULT])
def test_values_in_initialization_mode_equal_xml_start(built_fmu_sim, n_trailers):
    sim = built_fmu_sim(n_trailers)
    sim.fmu.setupExperiment(startTime=0.0)
    sim.fmu.enterInitializationMode()
    variables = [v for v in sim.md.modelVariables if v.start is not None]
    values = sim.get([v.name for v in variables])
    mismatched = {v.name: (got, xml_start(v)) for v, got in zip(variables, values, strict=True)
                  if got != xml_start(v)}
    assert mismatched == {}
    assert sim.get(["n"]) == [n_trailers]


def test_every_variable_reads_with_its_type_and_is_named_by_the_c_side(built_fmu_sim):
    """Every variable of the XML has a place in the C model (read through its type's getter)."""
    sim = built_fmu_sim(N_DEFAULT, logging_on=True)
    sim.initialize({"theta_start[1]": 0.3}, {"v_cmd": -0.1})
    values = sim.get([v.name for v in sim.md.modelVariables])
    assert len(values) == len(sim.md.modelVariables)
    assert all(np.isfinite(float(value)) for value in values)
    # a getter of another type refuses, naming the variable and both types
    with pytest.raises(FMICallException):
        sim.fmu.getReal([sim.vr("slipping[2]")])
    assert any("slipping[2]" in message and "Boolean" in message and "Real" in message
               for status, _, message in sim.messages if status >= 3), sim.messages


def _tail_x(front, rear, theta):
    """x of the last axle for a robot at x = 0: x_i = x_{i-1} - R_{i-1} cos th_{i-1} - F_i cos th_i
    (independent of the FMU)."""
    x = 0.0
    for i in range(1, len(theta)):
        x -= rear[i - 1] * np.cos(theta[i - 1]) + front[i - 1] * np.cos(theta[i])
    return x


@pytest.mark.parametrize("mode", ["instantiated", "initialization"])
def test_outputs_read_before_initialization_ends_follow_every_set(built_fmu_sim, mode):
    """The outputs are kept between reads (a read of current outputs does no model work): every
    set of a start value or parameter must make the next read recompute them."""
    sim = built_fmu_sim(N_DEFAULT, logging_on=True)
    if mode == "initialization":
        sim.fmu.setupExperiment(startTime=0.0)
        sim.fmu.enterInitializationMode()
    front, rear, theta = [0.52] * 3, [0.52] * 3, [0.0] * 4
    assert sim.real("x[3]") == pytest.approx(_tail_x(front, rear, theta), abs=1e-15)
    sim.set({"theta_start[2]": 0.5})
    theta[2] = 0.5
    assert sim.real("x[3]") == pytest.approx(_tail_x(front, rear, theta), abs=1e-15)
    assert sim.real("phi[3]") == pytest.approx(0.5, abs=1e-15)
    sim.set({"front[3]": 1.0})
    front[2] = 1.0
    assert sim.real("x[3]") == pytest.approx(_tail_x(front, rear, theta), abs=1e-15)
    sim.set({"mu[2]": 0.3})
    assert sim.real("F_lat_max[2]") == pytest.approx(0.3 * 42.1 * 9.81, rel=1e-15)
    sim.set({"payload[2]": 10.0})
    assert sim.real("F_lat_max[2]") == pytest.approx(0.3 * 52.1 * 9.81, rel=1e-15)
    # a parameter made invalid after a read: the next read checks it and fails, naming it
    sim.set({"front[1]": -1.0})
    with pytest.raises(FMICallException):
        sim.real("x[1]")
    assert any("outputs cannot be computed: front[1] = -1" in message
               for status, _, message in sim.messages if status >= 3), sim.messages


def test_get_real_of_many_values_equals_one_at_a_time(built_fmu_sim):
    """fmi2GetReal looks an array's storage up once for a run of its elements: runs, jumps
    between arrays, descending and repeated indices all read what single reads give, and a
    reference just past an array's last element is unknown."""
    import random

    sim = built_fmu_sim(N_DEFAULT, logging_on=True)
    sim.initialize({"slip_mode": 1, "theta_start[2]": 0.3, "front[2]": 0.6},
                   {"v_cmd": -0.05, "w_cmd": 0.2, "push_y": 60.0})
    for _ in range(10):
        sim.step(0.005)
    names = [v.name for v in sim.md.modelVariables if v.type == "Real"]
    single = {name: sim.real(name) for name in names}
    orders = [names, names[::-1], random.Random(1).sample(names, len(names)),
              [name for name in names for _ in range(2)]]
    for order in orders:
        assert list(sim.fmu.getReal([sim.vr(name) for name in order])) == [single[name]
                                                                           for name in order]
    x = [sim.vr(f"x[{i}]") for i in range(N_DEFAULT + 1)]
    with pytest.raises(FMICallException):
        sim.fmu.getReal([*x, x[-1] + 1])
    assert any(f"unknown value reference {x[-1] + 1}" in message
               for status, _, message in sim.messages if status >= 3), sim.messages


def test_get_boolean_reads_many_values_in_one_call(built_fmu_sim):
    """fmi2GetBoolean moves its values through a buffer a chunk at a time: a call of many
    values (several chunks) returns each one, and a wrong reference in a later chunk fails."""
    sim = built_fmu_sim(N_DEFAULT, logging_on=True)
    sim.initialize({"slip_mode": 1}, {"v_cmd": -0.05, "push_y": 60.0})  # 60 N > 37.2 N
    for _ in range(20):
        sim.step(0.005)
    names = ["slipping[1]", "slipping[2]", "slipping[3]", "jackknifed"]
    one_by_one = [bool(sim.fmu.getBoolean([sim.vr(name)])[0]) for name in names]
    assert one_by_one == [False, False, True, False]  # only the pushed trailer slides
    refs = [sim.vr(name) for name in names] * 50
    assert [bool(value) for value in sim.fmu.getBoolean(refs)] == one_by_one * 50
    with pytest.raises(FMICallException):
        sim.fmu.getBoolean(refs[:150] + [sim.vr("x[1]")] + refs[150:])
    assert any("x[1]" in message and "not a Boolean" in message
               for status, _, message in sim.messages if status >= 3), sim.messages


def test_outputs_are_finite_after_exit_initialization(built_fmu_sim):
    sim = built_fmu_sim(N_DEFAULT)
    sim.initialize({"theta_start[1]": 0.3, "v_start": -0.05, "w_start": 0.02},
                   {"v_cmd": -0.1, "w_cmd": 0.05})
    for block in (*OUTPUT_BLOCKS, "F_lat_max"):
        assert np.all(np.isfinite(sim.array(block))), block
    assert sim.array("F_lat_max") == pytest.approx(0.09 * 42.1 * 9.81, rel=1e-12)


# -- direct feedthrough ----------------------------------------------------------------------------
# Regimes in which the dependencies are probed: (parameters, inputs held while stepping there).
FEEDTHROUGH_REGIMES = {
    "rolling, slip_mode 0": (
        {"slip_mode": 0},
        {"v_cmd": -0.1, "w_cmd": 0.2, "push_x": 3.0, "push_y": -2.0, "slide[1]": 0.01,
         "slide[2]": -0.02, "slide[3]": 0.015}),
    "rolling, slip_mode 1": (
        {"slip_mode": 1, "mu[1]": 0.5, "mu[2]": 0.5, "mu[3]": 0.5},
        {"v_cmd": -0.1, "w_cmd": 0.2, "push_x": 3.0, "push_y": -2.0}),
    "sliding, slip_mode 1": (
        {"slip_mode": 1},
        {"v_cmd": -0.1, "w_cmd": 0.2, "push_x": 30.0, "push_y": -60.0}),
}


def _derived_dependencies(sim, inputs, outputs):
    """{output: inputs whose change (without a step) changes it}, by perturbing each input
    by small and large amounts from the current point and restoring it."""
    found = {name: set() for name in outputs}
    base = sim.get(outputs)
    for name in inputs:
        value = sim.real(name)
        for delta in (1e-6, -1e-3, 0.5, -50.0, 2e3):
            sim.set({name: value + delta})
            for out, old, new in zip(outputs, base, sim.get(outputs), strict=True):
                if new != old:
                    found[out].add(name)
        sim.set({name: value})
        assert sim.get(outputs) == base  # restoring the input restores every output
    return found


def test_declared_direct_feedthrough_is_what_the_fmu_does(built_fmu_sim):
    """For every output: the inputs listed in ModelStructure/Outputs are exactly those whose
    change, without a step, changes the output in some regime (perturbation through fmpy)."""
    md = built_fmu_sim(N_DEFAULT).md
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    declared = {unknown.variable.name: {d.name for d in (unknown.dependencies or [])}
                for unknown in md.outputs}
    assert sorted(declared) == sorted(outputs)

    derived = {name: set() for name in outputs}
    geometry = {"theta_start[1]": 0.3, "theta_start[2]": -0.4, "theta_start[3]": 0.5,
                "v_start": -0.1, "w_start": 0.2, "robot_acc_max": 50.0,
                "robot_alpha_max": 50.0}
    for regime, (params, held) in FEEDTHROUGH_REGIMES.items():
        sim = built_fmu_sim(N_DEFAULT, instance_name=regime)
        sim.initialize({**geometry, **params}, held)
        for _ in range(40):
            sim.step(0.005)
        if regime.startswith("sliding"):
            assert any(sim.array("slipping")) and max(abs(sim.array("slide_speed"))) > 1e-3
        probed = [name for name in inputs if not (params["slip_mode"] == 1 and "slide" in name)]
        for out, deps in _derived_dependencies(sim, probed, outputs).items():
            assert deps <= declared[out], (regime, out, deps - declared[out])
            derived[out] |= deps
    assert derived == declared


# -- instantiate ---------------------------------------------------------------------------------
def test_wrong_guid_fails_instantiate_with_a_message(built_fmu_sim, built_fmu_unzipped):
    _, md = built_fmu_unzipped(N_DEFAULT)
    wrong = "{00000000-0000-0000-0000-000000000000}"
    assert wrong != md.guid
    log: list = []
    with pytest.raises(Exception, match="[Ii]nstantiate"):
        built_fmu_sim(N_DEFAULT, logging_on=True, guid=wrong, messages=log)
    assert any(status >= 3 and "guid" in message.lower() for status, _, message in log), log


# -- FMU state -----------------------------------------------------------------------------------
def _trajectory(sim, h, steps, inputs_at):
    names = output_names(sim)
    rows = []
    for k in range(steps):
        sim.set(inputs_at(k))
        sim.step(h)
        rows.append(record(sim, names))
    return np.array(rows)


def test_get_set_fmu_state_rolls_back(built_fmu_sim):
    sim = built_fmu_sim(N_DEFAULT)
    sim.initialize({"theta_start[2]": 0.25}, {"v_cmd": -0.1, "w_cmd": 0.05})
    h = 0.02
    for _ in range(25):
        sim.step(h)
    saved = sim.fmu.getFMUstate()
    t_saved = sim.time

    def inputs_at(k):
        return {"v_cmd": -0.1 + 0.002 * k, "w_cmd": 0.05 * np.cos(0.1 * k), "push_x": 0.1 * k}

    first = _trajectory(sim, h, 60, inputs_at)
    sim.set({"v_cmd": -0.1, "w_cmd": 0.05, "push_x": 0.0})
    sim.fmu.setFMUstate(saved)
    sim.time = t_saved
    second = _trajectory(sim, h, 60, inputs_at)
    assert np.array_equal(first, second)

    # serialize, deserialize into a fresh instance initialised differently, replay
    blob = sim.fmu.serializeFMUstate(saved)
    assert isinstance(blob, bytes) and len(blob) > 0
    sim.fmu.freeFMUstate(saved)
    other = built_fmu_sim(N_DEFAULT, instance_name="other")
    other.initialize({"theta_start[1]": -0.4})
    restored = other.fmu.deSerializeFMUstate(blob)
    other.fmu.setFMUstate(restored)
    other.fmu.freeFMUstate(restored)
    other.time = t_saved
    third = _trajectory(other, h, 60, inputs_at)
    assert np.array_equal(first, third)


# -- doStep ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("h", [0.0, -0.01])
def test_step_size_not_positive_is_refused(built_fmu_sim, h):
    sim = built_fmu_sim(N_DEFAULT)
    sim.initialize()
    sim.step(0.01)
    with pytest.raises(FMICallException) as info:
        sim.fmu.doStep(currentCommunicationPoint=sim.time, communicationStepSize=h)
    assert info.value.status >= 3


@pytest.mark.parametrize("offset", [0.1, -0.005, 1e-3])
def test_wrong_communication_point_is_refused(built_fmu_sim, offset):
    sim = built_fmu_sim(N_DEFAULT)
    sim.initialize()
    sim.step(0.01)
    sim.step(0.01)
    with pytest.raises(FMICallException) as info:
        sim.fmu.doStep(currentCommunicationPoint=sim.time + offset, communicationStepSize=0.01)
    assert info.value.status >= 3


def _constant_speed_run(sim, points):
    """Step through the communication points ``points``; return x[0] at each."""
    xs = []
    for t0, t1 in zip(points[:-1], points[1:], strict=True):
        sim.fmu.doStep(currentCommunicationPoint=t0, communicationStepSize=t1 - t0)
        xs.append(sim.real("x[0]"))
    return np.array(xs)


def test_variable_and_inexact_steps_land_exactly(built_fmu_sim):
    """Steps with last-bit noise, nanosecond grids and odd sizes integrate exactly to t + h.

    With the robot moving straight at constant speed (v_start = v_cmd, theta = 0), x[0] is
    x0_start + v t exactly, so any dropped or extra substep time shows up in x[0].
    """
    speed = 1.0
    sim = built_fmu_sim(N_DEFAULT)
    sim.initialize({"v_start": speed}, {"v_cmd": speed})
    rng = np.random.default_rng(7)
    # fmpy-style t0 + k h with h having last-bit noise, then summed floats, then integer ns
    h_noisy = 0.0049999999999999992
    grid = [k * h_noisy for k in range(0, 201)]
    t = grid[-1]
    summed = [t]
    for h in (0.0049999999999999992, 0.0123, 1e-9, 0.0071, 0.013, 0.0049999999999999992):
        for _ in range(7):
            t = t + h
            summed.append(t)
    ns0 = int(round(t * 1e9))
    ns = np.cumsum(np.concatenate(([ns0], rng.integers(1, 20_000_000, size=60))))
    nanos = [t] + [int(v) * 1e-9 for v in ns[1:]]
    points = grid + summed[1:] + nanos[1:]
    xs = _constant_speed_run(sim, points)
    np.testing.assert_allclose(xs, speed * np.array(points[1:]), rtol=0, atol=1e-12)
    assert np.all(np.diff(points) > 0)


# -- state machine after an error (FMI 2.0: only get, set state, reset and free) -------------------
def _error_messages(sim):
    return [message for status, _, message in sim.messages if status >= 3]


REJECTED_CALLS = {
    "nan_input": lambda sim: sim.fmu.setReal([sim.vr("v_cmd")], [float("nan")]),
    "parameter_after_init": lambda sim: sim.fmu.setReal([sim.vr("mass[2]")], [50.0]),
    "unknown_reference": lambda sim: sim.fmu.getReal([99]),
    "wrong_type": lambda sim: sim.fmu.getInteger([sim.vr("x[0]")]),
    "unsupported_function": lambda sim: sim.fmu.getDirectionalDerivative(
        [sim.vr("x[0]")], [sim.vr("v_cmd")], [1.0]),
}


@pytest.mark.parametrize("rejected", sorted(REJECTED_CALLS))
def test_after_a_rejected_call_the_instance_cannot_step_on(built_fmu_sim, rejected):
    sim = built_fmu_sim(N_DEFAULT, logging_on=True)
    sim.initialize({"theta_start[1]": 0.2}, {"v_cmd": -0.1})
    sim.step(0.01)
    with pytest.raises(FMICallException) as info:
        REJECTED_CALLS[rejected](sim)
    assert info.value.status == 3
    first = _error_messages(sim)
    assert len(first) == 1
    # the message starts with the name of the function that refused (from __func__)
    assert first[0].startswith(info.value.function + ": "), (first, info.value.function)
    with pytest.raises(FMICallException) as step:
        sim.step(0.01)
    assert step.value.status == 3
    assert "fmi2DoStep" in _error_messages(sim)[-1] and "Error" in _error_messages(sim)[-1]
    with pytest.raises(FMICallException):
        sim.fmu.setReal([sim.vr("v_cmd")], [0.0])  # no more inputs either
    with pytest.raises(FMICallException):
        sim.fmu.terminate()
    # values stay readable for diagnostics, and a reset starts a fresh, working run
    assert np.all(np.isfinite(sim.array("x")))
    sim.fmu.reset()
    sim.initialize({"theta_start[1]": 0.2}, {"v_cmd": -0.1})
    sim.step(0.01)
    assert sim.real("v[0]") < 0.0


def test_a_state_saved_before_an_error_restarts_the_run(built_fmu_sim):
    """FMI 2.0: after fmi2Error the simulation may restart from a state saved before it."""
    sim = built_fmu_sim(N_DEFAULT)
    sim.initialize({"theta_start[1]": 0.2}, {"v_cmd": -0.1, "w_cmd": 0.1})
    sim.step(0.01)
    saved = sim.fmu.getFMUstate()
    sim.step(0.01)
    expected = sim.array("theta")
    with pytest.raises(FMICallException):
        sim.fmu.setReal([sim.vr("push_x")], [float("inf")])
    with pytest.raises(FMICallException):
        sim.fmu.doStep(currentCommunicationPoint=sim.time, communicationStepSize=0.01)
    sim.fmu.setFMUstate(saved)
    sim.fmu.freeFMUstate(saved)
    sim.time = 0.01
    sim.step(0.01)
    assert np.array_equal(sim.array("theta"), expected)


def test_a_call_in_the_wrong_mode_is_an_error_state_too(built_fmu_sim):
    sim = built_fmu_sim(N_DEFAULT, logging_on=True)
    with pytest.raises(FMICallException):
        sim.fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.01)
    assert "Instantiated" in _error_messages(sim)[-1]
    with pytest.raises(FMICallException):
        sim.fmu.setupExperiment(startTime=0.0)
    assert _error_messages(sim)[-1].startswith("fmi2SetupExperiment: not allowed in mode Error")


def test_unprovided_status_is_discard_and_stepping_goes_on(built_fmu_sim):
    from fmpy.fmi2 import fmi2DoStepStatus, fmi2LastSuccessfulTime

    sim = built_fmu_sim(N_DEFAULT)
    sim.initialize(inputs={"v_cmd": -0.1})
    sim.step(0.01)
    with pytest.raises(FMICallException) as info:
        sim.fmu.getStatus(fmi2DoStepStatus)
    assert info.value.status == 2  # fmi2Discard: "cannot be retrieved by the slave"
    assert sim.fmu.getRealStatus(fmi2LastSuccessfulTime) == pytest.approx(0.01)
    sim.step(0.01)
    assert sim.real("x[0]") < 0.0


# -- stop time ------------------------------------------------------------------------------------
def test_a_step_past_the_stop_time_is_refused(built_fmu_sim):
    sim = built_fmu_sim(N_DEFAULT, logging_on=True)
    sim.fmu.setupExperiment(startTime=0.0, stopTime=0.3)
    sim.fmu.enterInitializationMode()
    sim.fmu.exitInitializationMode()
    for _ in range(3):  # summed floats: 0.30000000000000004 ends "at" the stop time
        sim.step(0.1)
    assert sim.time != 0.3 and sim.time == pytest.approx(0.3)
    with pytest.raises(FMICallException) as info:
        sim.step(1e-6)
    assert info.value.status == 3
    message = _error_messages(sim)[-1]
    assert message.startswith("fmi2DoStep: ") and "stopTime = 0.2999999" in message


def test_no_stop_time_means_no_limit_and_reset_clears_it(built_fmu_sim):
    sim = built_fmu_sim(N_DEFAULT)
    sim.fmu.setupExperiment(startTime=0.0, stopTime=0.02)
    sim.fmu.reset()
    sim.initialize()  # setupExperiment without a stop time
    for _ in range(10):
        sim.step(0.01)
    assert sim.time == pytest.approx(0.1)


def test_simulate_fmu_with_its_stop_time_ends_there(built_fmu):
    result = simulate_fmu(str(built_fmu(N_DEFAULT)), stop_time=0.5, output_interval=0.005,
                          set_stop_time=True, output=["x[0]"])
    assert result["time"][-1] == pytest.approx(0.5)


def test_logging_on_does_not_log_every_step(built_fmu_sim):
    sim = built_fmu_sim(N_DEFAULT, logging_on=True)
    sim.initialize({"theta_start[1]": 0.2}, {"v_cmd": -0.1, "w_cmd": 0.05})
    before = len(sim.messages)
    for _ in range(300):
        sim.step(0.005)
    assert sim.messages[before:] == []
