"""Cost per 5 ms doStep of slip_mode 1 against slip_mode 0 (issue 6's benchmark).

Two regimes for slip_mode 1: rolling (every wheel within friction: kinematic RK4 plus a force
check per substep) and sliding (friction-impulse time stepping with 0.5 ms substeps; the push on
the last trailer exceeds friction and the robot turns fast so every wheel slides).
Target: mode 1 within 5x of mode 0. The sliding regime imposes the wheel constraints at the end
of each substep (a fixed point on the headings: two LCP set-ups per substep), so it costs about
twice what a start-of-substep constraint did; the rolling regime checks friction at both ends of
a substep.

Run: python benchmarks/bench_slip.py
"""

import math
import shutil
import tempfile
import time

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from pushtrain.fmu import build_fmu


def cost(n: int, slip_mode: int, sliding: bool, steps: int = 4000) -> tuple[float, int]:
    fmu = build_fmu(n)
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzip = tempfile.mkdtemp()
    extract(str(fmu), unzip)
    s = FMU2Slave(
        guid=md.guid, unzipDirectory=unzip, modelIdentifier="TrailerTrain", instanceName="b"
    )
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.setInteger([vr["slip_mode"]], [slip_mode])
    if sliding:  # mu small: every wheel slides while the robot swings
        s.setReal([vr[f"mu[{i}]"] for i in range(1, n + 1)], [0.002] * n)
    s.exitInitializationMode()
    slipping_refs = [vr[f"slipping[{i}]"] for i in range(1, n + 1)]
    h = 0.005
    slid = 0
    start = time.perf_counter()
    for k in range(steps):
        # sliding: abrupt +-0.3 rad/s swings; rolling: a smooth +-0.03 rad/s sine
        w = 0.3 * (1 if (k // 400) % 2 == 0 else -1) if sliding else 0.03 * math.sin(k * h)
        s.setReal([vr["v_cmd"], vr["w_cmd"]], [-0.05, w])
        s.doStep(k * h, h)
    per_step = (time.perf_counter() - start) / steps * 1e6
    slid = sum(s.getBoolean(slipping_refs))
    s.terminate()
    s.freeInstance()
    shutil.rmtree(unzip, ignore_errors=True)
    return per_step, slid


if __name__ == "__main__":
    print(f"{'n':>3} {'mode 0 us':>10} {'mode 1 rolling us':>18} {'mode 1 sliding us':>18} "
          f"{'rolling x':>9} {'sliding x':>9}")
    for n in (3, 10):
        m0, _ = cost(n, 0, False)
        m1r, _ = cost(n, 1, False)
        m1s, slid = cost(n, 1, True)
        print(f"{n:>3} {m0:>10.2f} {m1r:>18.2f} {m1s:>18.2f} {m1r / m0:>9.2f} {m1s / m0:>9.2f}"
              f"   (wheels sliding at the end: {slid}/{n})")
