"""Cost per 5 ms doStep of slip_mode 1 against slip_mode 0, n = 3 to 50 (issues 6 and 14).

Every run drives one FMU instance through raw ctypes calls per step (fmi2SetReal of the command,
fmi2DoStep, fmi2GetBoolean of the slipping flags), from rest:
- mode 0: rolling wheels under the whip command below (the reference cost);
- mode 1 rolling: the robot pulls the train (v > 0, stable at any n) with a gentle sine yaw
  rate: every wheel within friction (kinematic RK4 plus the friction check);
- mode 1 mixed: the robot swings +-0.3 rad/s on mu = 0.002: some wheels slide, others stick,
  wheels switch (friction impulses with sticking sets);
- mode 1 sliding: the robot whips its yaw rate +-2 rad/s at 1 Hz on mu = 0.0005: every wheel
  slides (the fraction of steps with every wheel sliding is printed).
The cost is the thread's CPU time per step (on a shared machine other processes stretch the
wall-clock time, not the CPU time), loop included; the loop alone (the same calls with the
doStep left out and no values moved) is printed for n = 50.

Targets (issue 14): slip_mode 1 with every wheel sliding <= 100 us per step at n = 50, and linear
in n from 10 to 50: the script prints cost(50) / cost(10) against 5 (linear) and 125 (cubic).
With --dense it also runs the dense O(n^3) solver this FMU had before (the tests' reference,
tests/csrc/slip_dense.c, compiled with the FMU's own sources in place of slip_solver.c) on the
mixed and sliding scenarios, fewer steps.

Run: python benchmarks/bench_slip.py [--dense]
"""

import argparse
import ctypes
import math
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import fmpy
import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from pushtrain.fmu.build import build_fmu

H = 0.005
DENSE_SOLVER = Path(__file__).resolve().parents[1] / "tests" / "csrc" / "slip_dense.c"
SIZES = (3, 10, 20, 30, 50)
# scenario: (slip_mode, parameters(n), command(k) -> (v_cmd, w_cmd))
SCENARIOS = {
    "mode 0": (0, lambda n: {"robot_alpha_max": 50.0},
               lambda k: (-0.05, 2.0 * math.sin(2 * math.pi * k * H))),
    "rolling": (1, lambda n: {}, lambda k: (0.05, 0.03 * math.sin(k * H))),
    "mixed": (1, lambda n: {f"mu[{i}]": 0.002 for i in range(1, n + 1)},
              lambda k: (-0.05, 0.3 if (k // 400) % 2 == 0 else -0.3)),
    "sliding": (1, lambda n: {"robot_alpha_max": 50.0,
                              **{f"mu[{i}]": 0.0005 for i in range(1, n + 1)}},
                lambda k: (-0.05, 2.0 * math.sin(2 * math.pi * k * H))),
}


def dense_reference(unzipdir: Path, target: Path) -> Path:
    """A copy of the extracted FMU rebuilt from its sources with the dense solver."""
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        raise SystemExit("--dense needs a C compiler (cc)")
    shutil.copytree(unzipdir, target)
    library = target / "binaries" / "linux64" / "TrailerTrain.so"
    sources = [str(path) for path in sorted((target / "sources").glob("*.c"))
               if path.name != "slip_solver.c"] + [str(DENSE_SOLVER)]
    subprocess.run([compiler, "-std=c99", "-O3", "-shared", "-fPIC", "-fvisibility=hidden",
                    f"-I{Path(fmpy.__file__).parent / 'c-code'}",
                    f"-I{target / 'sources'}", *sources, "-o", str(library), "-lm"], check=True)
    return target


def cost(unzipdir: Path, md, n: int, scenario: str, steps: int,
         bare: bool = False) -> tuple[float, float, float]:
    """(CPU us per step, fraction of wheel-steps sliding, fraction of steps with every wheel
    sliding). The loop makes only the three ctypes calls and a memmove of the flags; with
    ``bare`` the three calls move no values and there is no step (the loop's own cost)."""
    mode, params, command = SCENARIOS[scenario]
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = FMU2Slave(guid=md.guid, unzipDirectory=str(unzipdir), modelIdentifier="TrailerTrain",
                  instanceName="bench")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.setInteger([vr["slip_mode"]], [mode])
    values = params(n)
    if values:
        s.setReal([vr[name] for name in values], list(values.values()))
    s.exitInitializationMode()
    component = s.component
    set_real, do_step, get_boolean = s.dll.fmi2SetReal, s.dll.fmi2DoStep, s.dll.fmi2GetBoolean
    get_real = s.dll.fmi2GetReal
    command_refs = (ctypes.c_uint * 2)(vr["v_cmd"], vr["w_cmd"])
    commands = [(ctypes.c_double * 2)(*command(k)) for k in range(steps)]
    times = [ctypes.c_double(k * H) for k in range(steps)]
    h = ctypes.c_double(H)
    flag_refs = (ctypes.c_uint * n)(*(vr[f"slipping[{i}]"] for i in range(1, n + 1)))
    flags = (ctypes.c_int * n)()
    record = np.zeros((steps, n), dtype=np.int32)
    base, row = record.ctypes.data, 4 * n
    nothing = (ctypes.c_double * 1)()
    start = time.thread_time()
    for k in range(steps):
        if bare:  # three calls that do nothing, then the same memmove
            set_real(component, command_refs, 0, commands[k])
            get_real(component, command_refs, 0, nothing)
            get_boolean(component, flag_refs, 0, flags)
        else:
            set_real(component, command_refs, 2, commands[k])
            if do_step(component, times[k], h, 1) != 0:
                raise RuntimeError(f"{scenario}, n = {n}: fmi2DoStep failed at step {k}")
            get_boolean(component, flag_refs, n, flags)
        ctypes.memmove(base + k * row, flags, row)
    per_step = (time.thread_time() - start) / steps * 1e6
    s.terminate()
    s.freeInstance()
    return per_step, float(record.mean()), float(np.mean(record.all(axis=1)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dense", action="store_true",
                        help="also run the dense O(n^3) solver (before issue 14)")
    parser.add_argument("--steps", type=int, default=2000, help="steps per run (default 2000)")
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="bench_slip-"))
    print(f"CPU us per 5 ms step ({args.steps} steps from rest); x: ratio to mode 0")
    print(f"{'n':>3} {'mode 0':>8} {'rolling':>8} {'mixed':>8} {'sliding':>8} "
          f"{'rolling x':>9} {'mixed x':>8} {'sliding x':>9}  sliding wheels (rolling; mixed; "
          f"sliding, all-sliding steps)")
    results = {}
    try:
        for n in SIZES:
            fmu = build_fmu(n)
            md = read_model_description(str(fmu))
            unzipdir = Path(extract(str(fmu), unzipdir=str(work / f"n{n}")))
            row = {name: cost(unzipdir, md, n, name, args.steps) for name in SCENARIOS}
            row["loop"] = cost(unzipdir, md, n, "sliding", args.steps, bare=True)
            results[n] = row
            m0 = row["mode 0"][0]
            print(f"{n:>3} {m0:>8.2f} {row['rolling'][0]:>8.2f} {row['mixed'][0]:>8.2f} "
                  f"{row['sliding'][0]:>8.2f} {row['rolling'][0] / m0:>9.2f} "
                  f"{row['mixed'][0] / m0:>8.2f} {row['sliding'][0] / m0:>9.2f}  "
                  f"{row['rolling'][1]:.2f}; {row['mixed'][1]:.2f}; {row['sliding'][1]:.3f}, "
                  f"{row['sliding'][2]:.2f}",
                  flush=True)
            if args.dense:
                dense_dir = dense_reference(unzipdir, work / f"dense{n}")
                steps = max(40, min(args.steps, 200000 // n ** 2))
                for name in ("mixed", "sliding"):
                    dense, _, _ = cost(dense_dir, md, n, name, steps)
                    fast, _, _ = cost(unzipdir, md, n, name, steps)
                    print(f"      dense solver, {name:>7}: {dense:>10.1f} us against "
                          f"{fast:.1f} us ({dense / fast:.1f}x; {steps} steps)", flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    sliding = {n: results[n]["sliding"][0] for n in SIZES}
    mixed = {n: results[n]["mixed"][0] for n in SIZES}
    loop = results[50]["loop"][0]
    print(f"\nevery wheel sliding at n = 50: {sliding[50]:.1f} us per step (target <= 100 us), of "
          f"which the Python loop and its three ctypes calls {loop:.1f} us")
    print(f"linearity, sliding: cost(50) / cost(10) = {sliding[50] / sliding[10]:.2f} "
          f"(linear 5, cubic 125); per trailer "
          + ", ".join(f"n = {n}: {sliding[n] / n:.2f} us" for n in SIZES))
    print(f"linearity, mixed:   cost(50) / cost(10) = {mixed[50] / mixed[10]:.2f} "
          f"(linear 5, cubic 125)")
    for name, costs in (("sliding", sliding), ("mixed", mixed)):
        low, high = (costs[30] - costs[10]) / 20, (costs[50] - costs[30]) / 20
        print(f"added cost per trailer, {name}: n = 10..30 {low:.2f} us, n = 30..50 {high:.2f} us "
              f"(equal if linear; the second 2x the first if quadratic)")


if __name__ == "__main__":
    main()
