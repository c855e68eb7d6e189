"""The FMI 3.0 TrailerTrain FMU: one build for every n (structural parameter), array variables.

Checked against the FMI 2.0 builds of the same C model: with the same inputs every output agrees
to 1e-12 for n = 1, 3, 10 and 50 (fmpy's simulate_fmu with n set as a start value).
"""

from __future__ import annotations

import re
import shutil
import subprocess
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from pushtrain.fmu.build import build_fmu
from pushtrain.fmu.shapes import model_description_for
from pushtrain.fmu.variables import ARRAYS, DEFAULT_TRAILERS, MAX_TRAILERS, VR_STRIDE

FMI3_TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}
STATUS_ERROR = 3


@pytest.fixture(scope="session")
def fmu3_path():
    """The FMI 3.0 FMU, built once per session with -Werror."""
    return Path(build_fmu(fmi_version=3, strict=True))


@pytest.fixture(scope="session")
def fmu3_unzipped(fmu3_path, tmp_path_factory):
    unzipdir = extract(str(fmu3_path), unzipdir=str(tmp_path_factory.mktemp("trailertrain3")))
    return unzipdir, read_model_description(str(fmu3_path))


class Fmu3:
    """One FMU3Slave instance addressed by variable name, with its log messages."""

    def __init__(self, unzipped, name="train3"):
        unzipdir, md = unzipped
        self.md = md
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.messages: list[tuple[int, str]] = []
        self.fmu = FMU3Slave(guid=md.guid, unzipDirectory=unzipdir,
                             modelIdentifier="TrailerTrain", instanceName=name)
        self.fmu.instantiate(logMessage=self._log)
        self.time = 0.0

    def _log(self, env, status, category, message):
        self.messages.append((int(status), message.decode()))

    def errors(self) -> list[str]:
        return [text for status, text in self.messages if status >= STATUS_ERROR]

    def configure(self, n: int) -> None:
        self.fmu.enterConfigurationMode()
        self.fmu.setUInt64([self.vr["n"]], [n])
        self.fmu.exitConfigurationMode()

    def get(self, name: str, count: int = 1) -> np.ndarray:
        return np.array(self.fmu.getFloat64([self.vr[name]], nValues=count))

    def set(self, name: str, values) -> None:
        values = np.atleast_1d(np.asarray(values, dtype=float))
        self.fmu.setFloat64([self.vr[name]], list(values))

    def initialize(self) -> None:
        self.fmu.enterInitializationMode(startTime=0.0)
        self.fmu.exitInitializationMode()

    def step(self, h: float) -> None:
        self.fmu.doStep(self.time, h)
        self.time += h

    def free(self) -> None:
        self.fmu.freeInstance()


@pytest.fixture
def fmu3(fmu3_unzipped):
    made = []

    def make(**kwargs) -> Fmu3:
        made.append(Fmu3(fmu3_unzipped, **kwargs))
        return made[-1]

    yield make
    for sim in made:
        sim.free()


def _count(name: str, n: int) -> int:
    return next(block for block in ARRAYS if block.name == name).count(n)


# -- model description -------------------------------------------------------------------------
def test_validate_fmu_reports_no_problems(fmu3_path):
    assert validate_fmu(str(fmu3_path)) == []


def test_n_is_a_fixed_uint64_structural_parameter_1_to_50(fmu3_path):
    md = read_model_description(str(fmu3_path))
    assert md.fmiVersion == "3.0"
    (n,) = [v for v in md.modelVariables if v.name == "n"]
    assert (n.type, n.causality, n.variability) == ("UInt64", "structuralParameter", "fixed")
    with zipfile.ZipFile(fmu3_path) as zf:  # fmpy 0.3.32 reads no min/max of UInt64
        root = ET.fromstring(zf.read("modelDescription.xml"))
    (element,) = root.findall("./ModelVariables/UInt64[@name='n']")
    assert {key: element.get(key) for key in ("start", "min", "max")} == {
        "start": str(DEFAULT_TRAILERS), "min": "1", "max": str(MAX_TRAILERS)}
    cs = md.coSimulation
    assert cs.canHandleVariableCommunicationStepSize and cs.canGetAndSetFMUstate
    assert cs.canSerializeFMUstate and not cs.hasEventMode


def test_every_per_body_quantity_is_an_array_sized_by_n_or_n_plus_1(fmu3_path):
    """The FMI 2.0 contract's names, as arrays: n elements (Dimension n) or n + 1 (n_bodies)."""
    md = read_model_description(str(fmu3_path))
    xml = {v.name: v for v in md.modelVariables}
    fmi2 = {v.name.split("[")[0] for v in read_model_description(
        str(build_fmu(2))).modelVariables}
    assert set(xml) == (fmi2 | {"time", "n_bodies"})
    size_refs = {xml["n"].valueReference: "n", xml["n_bodies"].valueReference: "n_bodies"}
    for block in ARRAYS:
        var = xml[block.name]
        assert var.type == FMI3_TYPES[block.type], block.name
        assert var.causality == block.causality, block.name
        assert var.valueReference == VR_STRIDE * block.block, block.name
        (dim,) = var.dimensions
        expected = "n" if block.count(5) == 5 else "n_bodies"
        assert size_refs[dim.valueReference] == expected, block.name
        assert var.shape == (block.count(DEFAULT_TRAILERS),), block.name
        if block.start is not None:
            assert [float(s) for s in var.start.split()] == [block.start] * var.shape[0]


def test_value_references_equal_the_generated_c_enums(fmu3_path):
    with zipfile.ZipFile(fmu3_path) as zf:
        header = zf.read("sources/variables.h").decode()
    stride = int(re.search(r"#define VR_STRIDE (\d+)", header).group(1))
    enums = {}
    for kind in ("ScalarVr", "Block"):
        body = re.search(r"enum %s \{(.*?)\};" % kind, header, re.S).group(1)
        enums.update({k: int(v) for k, v in re.findall(r"(\w+)\s*=\s*(\d+)", body)})
    md = read_model_description(str(fmu3_path))
    for var in md.modelVariables:
        expected = (stride * enums[f"blk_{var.name}"] if var.dimensions
                    else enums[f"vr_{var.name}"])
        assert var.valueReference == expected, var.name
    assert len(enums) == len(md.modelVariables)


def test_archive_exports_every_fmi3_function_and_nothing_else(fmu3_path, tmp_path):
    """fmusim looks up all 75 functions of fmi3Functions.h; the headers are not vendored."""
    import fmpy

    if shutil.which("nm") is None:
        pytest.fail("binutils' nm is required to inspect the FMU's exported symbols")
    header = (Path(fmpy.__file__).parent / "c-code" / "fmi3Functions.h").read_text()
    declared = set(re.findall(r"^FMI3_Export fmi3\w+TYPE\s+(fmi3\w+);", header, re.M))
    assert len(declared) == 75
    with zipfile.ZipFile(fmu3_path) as zf:
        names = set(zf.namelist())
        zf.extract("binaries/x86_64-linux/TrailerTrain.so", tmp_path)
    assert {"sources/buildDescription.xml", "sources/fmi3.c", "sources/instance.c"} <= names
    assert not any(name.startswith("sources/fmi3Function") for name in names)
    out = subprocess.run(["nm", "-D", "--defined-only",
                          str(tmp_path / "binaries/x86_64-linux/TrailerTrain.so")],
                         check=True, capture_output=True, text=True).stdout
    exported = {line.split()[-1] for line in out.splitlines() if " T " in line}
    assert exported == declared


# -- the same physics as FMI 2.0 ----------------------------------------------------------------
def _inputs(stop: float) -> np.ndarray:
    t = np.arange(0.0, stop + 1e-9, 0.005)
    signals = np.zeros(t.size, dtype=[("time", float), ("v_cmd", float), ("w_cmd", float),
                                      ("push_x", float), ("push_y", float)])
    signals["time"] = t
    signals["v_cmd"] = -0.1 * np.cos(0.3 * t)
    signals["w_cmd"] = 0.4 * np.sin(0.7 * t)
    signals["push_x"] = 30.0 * np.sin(t)
    signals["push_y"] = np.where(np.floor(t / 1.5) % 2, 60.0, -60.0)
    return signals


@pytest.mark.parametrize("slip_mode", [0, 1])
@pytest.mark.parametrize("n", [1, 3, 10, 50])
def test_outputs_equal_the_fmi2_build_of_that_n(fmu3_path, built_fmu, n, slip_mode):
    """fmpy simulates the FMI 3.0 FMU with n set as a start value (arrays as start values too);
    every output equals the FMI 2.0 FMU's to 1e-12."""
    stop = 3.0
    payload = 5.0 + np.arange(n)  # a different value per trailer
    theta_start = 0.02 * np.arange(n + 1)
    common = dict(stop_time=stop, output_interval=0.005, step_size=0.005, input=_inputs(stop))
    recorded = [block for block in ARRAYS if block.causality in ("output", "calculatedParameter")]
    result3 = simulate_fmu(
        str(fmu3_path), model_description=model_description_for(fmu3_path, n),
        start_values={"n": n, "slip_mode": slip_mode, "payload": list(payload),
                      "theta_start": list(theta_start)},
        output=[block.name for block in recorded] + ["jackknifed"], **common)
    start2 = {"slip_mode": slip_mode}
    start2.update({f"payload[{i + 1}]": p for i, p in enumerate(payload)})
    start2.update({f"theta_start[{i}]": a for i, a in enumerate(theta_start)})
    output2 = [f"{block.name}[{block.first + k}]" for block in recorded
               for k in range(block.count(n))]
    result2 = simulate_fmu(str(built_fmu(n)), start_values=start2,
                           output=output2 + ["jackknifed"], **common)
    assert result3.shape == result2.shape
    compared = 0
    for block in recorded:
        got = np.asarray(result3[block.name], dtype=float)
        assert got.shape == (len(result2), block.count(n)), block.name
        for k in range(block.count(n)):
            expected = np.asarray(result2[f"{block.name}[{block.first + k}]"], dtype=float)
            np.testing.assert_allclose(got[:, k], expected, rtol=1e-12, atol=1e-12,
                                       err_msg=f"{block.name}[{block.first + k}], n = {n}")
            compared += 1
    np.testing.assert_array_equal(result3["jackknifed"], result2["jackknifed"])
    # x, y, theta, v, w (n + 1 each); phi, F_lat, F_lat_max, slipping, hitch_fx, hitch_fy,
    # slide_speed (n each)
    assert compared == 5 * (n + 1) + 7 * n
    assert np.any(np.asarray(result2["slipping[1]"])), "the inputs must exercise the forces"


def test_two_instances_with_different_n_run_side_by_side(fmu3):
    """fmpy loads one copy of the library: n lives in each instance, not in the library."""
    def started(n: int, name: str) -> Fmu3:
        sim = fmu3(name=name)
        sim.configure(n)
        sim.initialize()
        sim.set("v_cmd", -0.1)
        sim.set("w_cmd", 0.3)
        return sim

    def run(sims: list[Fmu3]) -> None:
        for _ in range(200):
            for sim in sims:
                sim.step(0.005)

    solo = []
    for n in (2, 7):
        sim = started(n, f"solo{n}")
        run([sim])
        solo.append(sim.get("theta", n + 1))
    pair = [started(2, "a"), started(7, "b")]
    run(pair)
    for alone, sim, n in zip(solo, pair, (2, 7), strict=True):
        np.testing.assert_array_equal(sim.get("theta", n + 1), alone)
        assert alone.size == n + 1 and np.ptp(alone) > 0.01


def test_variable_steps_and_fmu_state_roundtrip(fmu3):
    sim = fmu3()
    sim.configure(4)
    sim.initialize()
    sim.set("v_cmd", -0.2)
    sim.set("w_cmd", 0.5)
    sim.set("slide", [0.0, 0.0, 0.0, 0.01])
    for h in (0.005, 0.0049999999999999992, 0.01, 0.002):  # importers' steps vary
        sim.step(h)
    state = sim.fmu.getFMUState()
    t_saved = sim.time
    for _ in range(50):
        sim.step(0.005)
    first = sim.get("x", 5)
    serialized = sim.fmu.serializeFMUState(state)
    sim.fmu.setFMUState(sim.fmu.deserializeFMUState(serialized))
    sim.time = t_saved
    for _ in range(50):
        sim.step(0.005)
    np.testing.assert_array_equal(sim.get("x", 5), first)
    assert sim.errors() == []


def test_start_values_in_the_xml_are_what_the_fmu_reports(fmu3, fmu3_unzipped):
    _, md = fmu3_unzipped
    sim = fmu3()
    for var in md.modelVariables:
        if var.start is None:
            continue
        count = var.shape[0] if var.shape else 1
        getter = {"Float64": sim.fmu.getFloat64, "Int32": sim.fmu.getInt32,
                  "UInt64": sim.fmu.getUInt64}[var.type]
        got = getter([var.valueReference], nValues=count)
        assert [float(v) for v in got] == [float(s) for s in var.start.split()], var.name


# -- n: set before initialization, resizes the arrays ------------------------------------------
def test_setting_n_resizes_every_array_and_restarts_their_values(fmu3):
    sim = fmu3()
    sim.set("front", [0.6, 0.6, 0.6])
    sim.configure(5)  # a dimension change invalidates the old values (FMI 3.0, 2.4.7.5)
    assert sim.fmu.getUInt64([sim.vr["n"], sim.vr["n_bodies"]]) == [5, 6]
    np.testing.assert_array_equal(sim.get("front", 5), [0.52] * 5)
    np.testing.assert_allclose(sim.get("x", 6), -1.04 * np.arange(6), rtol=0, atol=1e-12)
    sim.set("front", [0.6] * 5)
    sim.configure(5)  # the same n again keeps the values
    np.testing.assert_array_equal(sim.get("front", 5), [0.6] * 5)
    sim.fmu.setUInt64([sim.vr["n"]], [2])  # fmpy's simulate_fmu sets n in Instantiated
    sim.initialize()
    assert sim.get("theta", 3).size == 3 and sim.errors() == []


@pytest.mark.parametrize("bad", [0, 51, 2**64 - 1])
@pytest.mark.parametrize("where", ["configuration", "instantiated"])
def test_n_out_of_range_is_an_error_naming_n(fmu3, bad, where):
    sim = fmu3()
    if where == "configuration":
        sim.fmu.enterConfigurationMode()
    with pytest.raises(FMICallException) as info:
        sim.fmu.setUInt64([sim.vr["n"]], [bad])
    assert info.value.function == "fmi3SetUInt64" and info.value.status == STATUS_ERROR
    assert sim.errors() == [f"fmi3SetUInt64: n = {bad}: allowed 1 to 50 (the FMU's arrays hold "
                            "1 to 50 trailers)"]


@pytest.mark.parametrize("when", ["initialization", "step"])
def test_setting_n_once_initialization_began_is_an_error_naming_n(fmu3, when):
    sim = fmu3()
    sim.fmu.enterInitializationMode(startTime=0.0)
    if when == "step":
        sim.fmu.exitInitializationMode()
    with pytest.raises(FMICallException):
        sim.fmu.setUInt64([sim.vr["n"]], [4])
    (message,) = sim.errors()
    assert message.startswith("fmi3SetUInt64: n is a structural parameter (now n = 3): it can "
                              "be set only before initialization")
    with pytest.raises(FMICallException):  # and the instance stays stopped
        sim.fmu.doStep(0.0, 0.005)


def test_no_reconfiguration_of_the_fixed_n(fmu3):
    sim = fmu3()
    sim.initialize()
    with pytest.raises(FMICallException):
        sim.fmu.enterConfigurationMode()
    assert "no Reconfiguration Mode: n is a fixed structural parameter" in sim.errors()[0]


@pytest.mark.parametrize("name, given, n", [("front", 4, 5), ("theta_start", 5, 5),
                                            ("slide", 6, 5), ("x", 5, 5)])
def test_array_lengths_that_do_not_match_n_are_an_error_naming_the_variable(fmu3, name, given,
                                                                          n):
    sim = fmu3()
    sim.configure(n)
    size = _count(name, n)
    with pytest.raises(FMICallException) as info:
        if name == "x":
            sim.fmu.getFloat64([sim.vr[name]], nValues=given)
        else:
            sim.set(name, [0.1] * given)
    assert info.value.status == STATUS_ERROR
    (message,) = sim.errors()
    if given < size:
        assert message.endswith(f"{name} has {size} values (n = {n}) but nValues = {given} "
                                f"leaves room for {given}"), message
    else:
        assert message.endswith(f"nValues = {given} but the 1 variable holds {size} values "
                                f"(n = {n})"), message


def test_n_bodies_must_follow_n(fmu3):
    sim = fmu3()
    sim.fmu.enterConfigurationMode()
    sim.fmu.setUInt64([sim.vr["n"], sim.vr["n_bodies"]], [4, 5])  # consistent: accepted
    sim.fmu.exitConfigurationMode()
    sim.fmu.enterConfigurationMode()
    sim.fmu.setUInt64([sim.vr["n_bodies"]], [9])
    with pytest.raises(FMICallException):
        sim.fmu.exitConfigurationMode()
    assert sim.errors() == ["fmi3ExitConfigurationMode: n_bodies = 9: must be n + 1 = 5 "
                            "(n_bodies follows n: set n alone)"]


def test_only_structural_parameters_in_configuration_mode(fmu3):
    sim = fmu3()
    sim.fmu.enterConfigurationMode()
    with pytest.raises(FMICallException):
        sim.set("mass", [40.0] * 3)
    assert sim.errors() == ["fmi3SetFloat64: mass cannot be set in Configuration Mode: only the "
                            "structural parameters (n, n_bodies) can; leave it with "
                            "fmi3ExitConfigurationMode first"]


def test_an_element_out_of_its_bound_is_named_with_its_body_index(fmu3):
    sim = fmu3()
    sim.configure(4)
    sim.set("mu", [0.09, 0.09, 3.0, 0.09])
    sim.fmu.enterInitializationMode(startTime=0.0)
    with pytest.raises(FMICallException):
        sim.fmu.exitInitializationMode()
    (message,) = sim.errors()
    assert message.startswith("fmi3ExitInitializationMode: mu[3] = 3: allowed 0 to 2 ")


def test_event_mode_and_model_exchange_are_refused_by_name(fmu3_unzipped):
    unzipdir, md = fmu3_unzipped
    log = []
    fmu = FMU3Slave(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier="TrailerTrain")
    with pytest.raises(Exception, match="[Ii]nstantiate"):
        fmu.instantiate(eventModeUsed=True, logMessage=lambda *a: log.append(a[3].decode()))
    assert log == ["fmi3InstantiateCoSimulation: eventModeUsed = true, but hasEventMode = false "
                   "(TrailerTrain has no events)"]
    fmu.freeLibrary()


# Exported functions of capabilities the FMU has not (fmi3.c's NOT_SUPPORTED) and the flag each
# names: events, clocks, dependencies, derivatives, Model Exchange, Scheduled Execution.
NOT_SUPPORTED = [
    ("fmi3EnterEventMode", "hasEventMode = false"),
    ("fmi3UpdateDiscreteStates", "hasEventMode = false"),
    ("fmi3EvaluateDiscreteStates", "providesEvaluateDiscreteStates = false"),
    ("fmi3EnterStepMode", "hasEventMode = false: fmi3ExitInitializationMode enters Step Mode"),
    ("fmi3GetClock", "TrailerTrain has no clocks"),
    ("fmi3SetShiftFraction", "TrailerTrain has no clocks"),
    ("fmi3GetVariableDependencies", "providesPerElementDependencies = false"),
    ("fmi3GetAdjointDerivative", "providesAdjointDerivatives = false"),
    ("fmi3GetOutputDerivatives", "maxOutputDerivativeOrder = 0"),
    ("fmi3SetTime", "Model Exchange: TrailerTrain is a Co-Simulation FMU only"),
    ("fmi3GetNumberOfContinuousStates", "Model Exchange: TrailerTrain is a Co-Simulation FMU only"),
    ("fmi3ActivateModelPartition", "TrailerTrain has no <ScheduledExecution>"),
]


@pytest.mark.parametrize("function, why", NOT_SUPPORTED)
def test_a_capability_the_fmu_has_not_is_an_error_naming_function_and_flag(fmu3, function, why):
    sim = fmu3()
    sim.initialize()
    call = getattr(sim.fmu.dll, function)
    zeros = [kind() for kind in call.argtypes[1:]]  # NULL pointers, 0: the stubs read none
    assert call(sim.fmu.component, *zeros) == STATUS_ERROR
    assert sim.errors() == [f"{function}: not supported ({why})"]
    with pytest.raises(FMICallException):  # the instance is in the error state
        sim.step(0.005)
