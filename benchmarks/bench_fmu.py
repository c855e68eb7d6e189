"""Cost of the TrailerTrain FMU per 5 ms communication step (issue 2's benchmark).

For each n: microseconds per ``doStep`` of 5 ms through fmpy's FMU2Slave (Python + ctypes + model),
and the model's own share, measured by letting one ``doStep`` of 5 s cover 1000 internal 5 ms
substeps. Target: model work for n = 3 under 2 us per 5 ms step, growing at most linearly in n.
Also the cost of one ``fmi2GetReal`` of every Real output (raw ctypes call) in Initialization Mode
and after a step: the outputs are computed once per call, so it grows like values + n, not
values * n.

Run: python benchmarks/bench_fmu.py
"""

import ctypes
import shutil
import tempfile
import time

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave, fmi2Real, fmi2ValueReference

from pushtrain.fmu import build_fmu


def _slave(fmu):
    md = read_model_description(str(fmu))
    unzip = tempfile.mkdtemp()
    extract(str(fmu), unzip)
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier="TrailerTrain",
                  instanceName="bench")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s.enterInitializationMode()
    s.exitInitializationMode()
    s.setReal([vr["v_cmd"], vr["w_cmd"]], [-0.08, 0.01])
    return s, unzip


def bench(n: int, steps: int = 20000) -> tuple[float, float]:
    fmu = build_fmu(n)
    s, unzip = _slave(fmu)
    h, t = 0.005, 0.0
    start = time.perf_counter()
    for k in range(steps):
        s.doStep(k * h, h)
    per_step = (time.perf_counter() - start) / steps * 1e6
    t = steps * h
    big = 1000 * h  # one doStep covering 1000 internal 5 ms substeps
    reps = 50
    start = time.perf_counter()
    for k in range(reps):
        s.doStep(t + k * big, big)
    model = (time.perf_counter() - start) / (reps * 1000) * 1e6
    s.terminate()
    s.freeInstance()
    shutil.rmtree(unzip, ignore_errors=True)
    return per_step, model


def get_all_outputs(n: int, calls: int = 2000) -> tuple[int, float, float]:
    """(number of Real outputs, us per fmi2GetReal of all in Initialization Mode, after a step)."""
    fmu = build_fmu(n)
    md = read_model_description(str(fmu))
    refs = [v.valueReference for v in md.modelVariables
            if v.causality == "output" and v.type == "Real"]
    unzip = tempfile.mkdtemp()
    extract(str(fmu), unzip)
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier="TrailerTrain",
                  instanceName="bench")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    vr = (fmi2ValueReference * len(refs))(*refs)
    out = (fmi2Real * len(refs))()

    def per_call() -> float:
        start = time.perf_counter()
        for _ in range(calls):
            s.fmi2GetReal(s.component, vr, ctypes.c_size_t(len(refs)), out)
        return (time.perf_counter() - start) / calls * 1e6

    init = per_call()
    s.exitInitializationMode()
    s.doStep(0.0, 0.005)
    stepping = per_call()
    s.terminate()
    s.freeInstance()
    shutil.rmtree(unzip, ignore_errors=True)
    return len(refs), init, stepping


if __name__ == "__main__":
    print(f"{'n':>3} {'us/doStep (fmpy)':>18} {'model us/5ms step':>18} {'model us/trailer':>17}")
    for n in (3, 10, 20, 50):
        per_step, model = bench(n)
        print(f"{n:>3} {per_step:>18.2f} {model:>18.3f} {model / n:>17.3f}")
    print(f"\n{'n':>3} {'Real outputs':>13} {'us/getReal(all), init':>22} "
          f"{'us/getReal(all), stepping':>26}")
    for n in (3, 10, 50):
        count, init, stepping = get_all_outputs(n)
        print(f"{n:>3} {count:>13} {init:>22.2f} {stepping:>26.2f}")
