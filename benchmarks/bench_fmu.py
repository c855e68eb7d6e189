"""Cost of the TrailerTrain FMU per 5 ms communication step (issue 2's benchmark).

For each n: microseconds per ``doStep`` of 5 ms through fmpy's FMU2Slave (Python + ctypes + model),
and the model's own share, measured by letting one ``doStep`` of 5 s cover 1000 internal 5 ms
substeps. Target: model work for n = 3 under 2 us per 5 ms step, growing at most linearly in n.

Run: python benchmarks/bench_fmu.py
"""

import shutil
import tempfile
import time

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

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


if __name__ == "__main__":
    print(f"{'n':>3} {'us/doStep (fmpy)':>18} {'model us/5ms step':>18} {'model us/trailer':>17}")
    for n in (3, 10, 20, 50):
        per_step, model = bench(n)
        print(f"{n:>3} {per_step:>18.2f} {model:>18.3f} {model / n:>17.3f}")
