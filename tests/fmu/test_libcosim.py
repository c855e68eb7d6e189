"""The TrailerTrain FMU in Open Simulation Platform's libcosim (through libcosimpy).

libcosim is an independent FMI importer: it steps on integer nanoseconds, sets parameters after
fmi2EnterInitializationMode and runs the FMU on a worker thread. Its trajectory must equal
fmpy's for the same inputs and steps.
"""

from __future__ import annotations

import numpy as np
import pytest

libcosim_execution = pytest.importorskip("libcosimpy.CosimExecution")
from libcosimpy.CosimEnums import CosimExecutionState  # noqa: E402
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level  # noqa: E402
from libcosimpy.CosimManipulator import CosimManipulator  # noqa: E402
from libcosimpy.CosimObserver import CosimObserver  # noqa: E402
from libcosimpy.CosimSlave import CosimLocalSlave  # noqa: E402

CosimExecution = libcosim_execution.CosimExecution

N = 3
STEP_NS = 10_000_000  # 0.01 s
COMPARED = [f"{block}[{i}]" for block in ("x", "y", "theta") for i in range(N + 1)]
COMPARED += [f"{block}[{i}]" for block in ("phi", "F_lat", "hitch_fx") for i in range(1, N + 1)]
COMPARED += ["v[0]", "w[0]", f"v[{N}]", f"w[{N}]"]


def cosim_run(fmu_path, md, initial, checkpoints, override=None):
    """Run libcosim; return {step_count: values of COMPARED} at the checkpoints (step counts).

    ``override`` = (step_count, {name: value}) sets Real values through an override
    manipulator before that step.
    """
    log_output_level(CosimLogLevel.ERROR)
    refs = {v.name: v.valueReference for v in md.modelVariables}
    execution = CosimExecution.from_step_size(step_size=STEP_NS)
    slave = CosimLocalSlave(fmu_path=str(fmu_path), instance_name="train")
    index = execution.add_local_slave(local_slave=slave)
    assert index >= 0
    observer = CosimObserver.create_last_value()
    assert execution.add_observer(observer=observer)
    manipulator = CosimManipulator.create_override()
    assert execution.add_manipulator(manipulator=manipulator)
    for name, value in initial.items():
        assert execution.real_initial_value(index, refs[name], float(value)), name
    out = {}
    done = 0
    for target in sorted(checkpoints):
        if override is not None and done <= override[0] < target:
            assert execution.step(override[0] - done)
            done = override[0]
            names = list(override[1])
            assert manipulator.slave_real_values(index, [refs[n] for n in names],
                                                 [float(override[1][n]) for n in names])
        assert execution.step(target - done), "libcosim step failed"
        done = target
        out[target] = np.array(observer.last_real_values(index, [refs[n] for n in COMPARED]))
    assert execution.status().state == CosimExecutionState.STOPPED.value
    return out


def fmpy_run(sim, initial, checkpoints, override=None):
    """The same run with fmpy's FMU2Slave on the same nanosecond grid."""
    params = {k: v for k, v in initial.items() if sim.variables[k].causality == "parameter"}
    inputs = {k: v for k, v in initial.items() if sim.variables[k].causality == "input"}
    sim.initialize(params, inputs)
    out = {}
    for k in range(max(checkpoints)):
        if override is not None and k == override[0]:
            sim.set(override[1])
        t0, t1 = k * STEP_NS * 1e-9, (k + 1) * STEP_NS * 1e-9
        sim.fmu.doStep(currentCommunicationPoint=t0, communicationStepSize=t1 - t0)
        if k + 1 in checkpoints:
            out[k + 1] = np.array(sim.get(COMPARED))
    return out


@pytest.fixture
def fmu_n3(built_fmu, built_fmu_unzipped):
    path = built_fmu(N)
    _, md = built_fmu_unzipped(N)
    return path, md


CHECKPOINTS = [1, 7, 50, 200, 500]


def test_libcosim_trajectory_equals_fmpy(fmu_n3, built_fmu_sim):
    path, md = fmu_n3
    initial = {"v_cmd": -0.1, "w_cmd": 0.05, "theta_start[2]": 0.15, "push_x": 2.0}
    cosim = cosim_run(path, md, initial, CHECKPOINTS)
    reference = fmpy_run(built_fmu_sim(N), initial, CHECKPOINTS)
    for k in CHECKPOINTS:
        np.testing.assert_allclose(cosim[k], reference[k], rtol=1e-9, atol=1e-9,
                                   err_msg=f"after {k} steps")
    # the chain really moved and turned
    moved = cosim[CHECKPOINTS[-1]] - cosim[CHECKPOINTS[0]]
    assert abs(moved[COMPARED.index("x[0]")]) > 0.3
    assert abs(moved[COMPARED.index("theta[0]")]) > 0.1


def test_libcosim_override_of_inputs_midway(fmu_n3, built_fmu_sim):
    path, md = fmu_n3
    initial = {"v_cmd": -0.1, "w_cmd": 0.05}
    override = (120, {"v_cmd": 0.15, "w_cmd": -0.08, "push_y": -5.0})
    checkpoints = [100, 121, 300]
    cosim = cosim_run(path, md, initial, checkpoints, override)
    reference = fmpy_run(built_fmu_sim(N), initial, checkpoints, override)
    for k in checkpoints:
        np.testing.assert_allclose(cosim[k], reference[k], rtol=1e-9, atol=1e-9,
                                   err_msg=f"after {k} steps")


def test_libcosim_parameters_take_effect(fmu_n3, built_fmu_sim):
    """libcosim sets parameters in Initialization Mode; they must change the motion."""
    path, md = fmu_n3
    changed = {"v_cmd": -0.1, "w_cmd": 0.05, "front[1]": 0.8, "rear[1]": 0.35,
               "mass[2]": 90.0, "x0_start": 1.0}
    default = {"v_cmd": -0.1, "w_cmd": 0.05}
    checkpoints = [1, 300]
    cosim = cosim_run(path, md, changed, checkpoints)
    cosim_default = cosim_run(path, md, default, checkpoints)
    reference = fmpy_run(built_fmu_sim(N), changed, checkpoints)
    for k in checkpoints:
        np.testing.assert_allclose(cosim[k], reference[k], rtol=1e-9, atol=1e-9)
    x1 = COMPARED.index("x[1]")
    # front[1] = 0.8 instead of 0.52 and x0_start = 1: trailer 1 starts 1 - 0.28 m further
    assert cosim[1][x1] - cosim_default[1][x1] == pytest.approx(1.0 - 0.28, abs=0.01)
    lateral = COMPARED.index("F_lat[2]")
    assert abs(cosim[300][lateral] - cosim_default[300][lateral]) > 1e-6
