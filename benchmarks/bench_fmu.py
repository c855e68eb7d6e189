"""Cost of the TrailerTrain FMU per 5 ms communication step (issue 2's benchmark).

For each n: microseconds per ``doStep`` of 5 ms through fmpy's FMU2Slave (Python + ctypes + model),
and the model's own share, measured by letting one ``doStep`` of 5 s cover 1000 internal 5 ms
substeps. Target: model work for n = 3 under 2 us per 5 ms step, growing at most linearly in n.
Also the cost of one ``fmi2GetReal`` of every Real output and one ``fmi2GetBoolean`` of every
Boolean output (raw ctypes calls; issue 14): the outputs are computed once after each step or set
and kept, so a read costs O(values) (a copy per value) and a read after an input set O(n + values),
never values * n. Printed against the cost of one 5 ms ``fmi2DoStep`` of the same instance
(thread CPU time per call, the least of 5 runs).

Run: python benchmarks/bench_fmu.py
"""

import ctypes
import math
import shutil
import tempfile
import time

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave, fmi2Real, fmi2ValueReference

from pushtrain.fmu.build import build_fmu


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


def get_all_outputs(n: int, calls: int = 2000) -> dict:
    """Raw ctypes calls on one instance, us per call: fmi2GetReal of every Real output in
    Initialization Mode, right after a step (the outputs are current: a copy per value), after an
    input set (recomputed once, then a copy per value); fmi2GetBoolean of every Boolean output
    after a step; and fmi2DoStep of 5 ms (the model's step, for the ratio)."""
    fmu = build_fmu(n)
    md = read_model_description(str(fmu))
    refs = [v.valueReference for v in md.modelVariables
            if v.causality == "output" and v.type == "Real"]
    flag_refs = [v.valueReference for v in md.modelVariables
                 if v.causality == "output" and v.type == "Boolean"]
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzip = tempfile.mkdtemp()
    extract(str(fmu), unzip)
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier="TrailerTrain",
                  instanceName="bench")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    dll, component = s.dll, s.component
    real_vr = (fmi2ValueReference * len(refs))(*refs)
    real_out = (fmi2Real * len(refs))()
    flag_vr = (fmi2ValueReference * len(flag_refs))(*flag_refs)
    flag_out = (ctypes.c_int * len(flag_refs))()
    input_vr = (fmi2ValueReference * 1)(vr["w_cmd"])
    input_value = (fmi2Real * 1)()

    def per_call(call, repeats: int = 5) -> float:
        """Thread CPU time per call, the least of ``repeats`` runs (others' load only adds)."""
        best = math.inf
        for r in range(repeats):
            start = time.thread_time()
            for k in range(r * calls, (r + 1) * calls):  # k goes on: the step's time does
                call(k)
            best = min(best, (time.thread_time() - start) / calls * 1e6)
        return best

    def get_reals(_k):
        dll.fmi2GetReal(component, real_vr, len(refs), real_out)

    def set_then_get(k):
        input_value[0] = 0.01 * (k % 2)
        dll.fmi2SetReal(component, input_vr, 1, input_value)
        dll.fmi2GetReal(component, real_vr, len(refs), real_out)

    def set_only(k):
        input_value[0] = 0.01 * (k % 2)
        dll.fmi2SetReal(component, input_vr, 1, input_value)

    def get_flags(_k):
        dll.fmi2GetBoolean(component, flag_vr, len(flag_refs), flag_out)

    def step(k):
        dll.fmi2DoStep(component, ctypes.c_double(k * 0.005), ctypes.c_double(0.005), 1)

    result = {"reals": len(refs), "booleans": len(flag_refs), "init": per_call(get_reals)}
    s.exitInitializationMode()
    result["step"] = per_call(step)
    result["after_step"] = per_call(get_reals)
    result["after_set"] = per_call(set_then_get) - per_call(set_only)
    result["booleans_after_step"] = per_call(get_flags)
    s.terminate()
    s.freeInstance()
    shutil.rmtree(unzip, ignore_errors=True)
    return result


if __name__ == "__main__":
    print(f"{'n':>3} {'us/doStep (fmpy)':>18} {'model us/5ms step':>18} {'model us/trailer':>17}")
    for n in (3, 10, 20, 50):
        per_step, model = bench(n)
        print(f"{n:>3} {per_step:>18.2f} {model:>18.3f} {model / n:>17.3f}")
    print(f"\n{'n':>3} {'Reals':>6} {'getReal, init':>14} {'after step':>11} {'after set':>10} "
          f"{'Booleans':>9} {'getBoolean':>11} {'doStep':>8} {'getReal/doStep':>15}  (us per call)")
    for n in (3, 10, 50):
        r = get_all_outputs(n)
        print(f"{n:>3} {r['reals']:>6} {r['init']:>14.2f} {r['after_step']:>11.2f} "
              f"{r['after_set']:>10.2f} {r['booleans']:>9} {r['booleans_after_step']:>11.2f} "
              f"{r['step']:>8.2f} {r['after_step'] / r['step']:>15.2f}")
