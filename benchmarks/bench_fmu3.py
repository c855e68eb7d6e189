"""The FMI 3.0 TrailerTrain FMU (issue 17): build time, agreement with FMI 2.0, other importers.

1. Build time of the one FMI 3.0 FMU against one FMI 2.0 build (forced, in a fresh cache).
2. Agreement: fmpy runs the FMI 3.0 FMU with n = 1, 3, 10, 50 (n as a start value, nonzero
   inputs, slip_mode 0 and 1) and the FMI 2.0 build of that n; the largest |difference| of any
   output and whether the two are bit-identical.
3. fmusim (Reference-FMUs; not on PyPI): pass ``--fmusim PATH``. Build it as in
   /work/shared/fmi-check/RECIPES.md section 1 (Reference-FMUs commit c8d4e6d, one ``cc`` call,
   about 30 s; Debian packages libxml2-dev libminizip-dev libsundials-dev zlib1g-dev). fmusim
   sets n in Configuration Mode; its CSV (arrays as space-separated cells) is compared with fmpy.
4. ecos (PyPI ``ecospy==0.7.2``, needs Debian ``libtbb12``): if importable. ecos 0.7.2 sets
   parameters after fmi3EnterInitializationMode, where the FMU refuses n (a structural
   parameter), and reads every variable as one value, where the FMU refuses the arrays (nValues
   does not match): it runs the FMU at the default n = 3 through its scalars only. Checked: the
   step at which ``jackknifed`` turns true equals fmpy's.
5. Cost per step of the master's wrapper (cosim/fmu_slave.py): the master's reads and writes and
   one doStep, FMI 2.0 against FMI 3.0, n = 3 and 50.

Run: python benchmarks/bench_fmu3.py [--fmusim PATH] [--skip-build-time]
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import math
import os
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
from fmpy import simulate_fmu

from pushtrain.cosim.fmu_slave import TrailerTrainSlave
from pushtrain.fmu.build import build_fmu
from pushtrain.fmu.shapes import model_description_for
from pushtrain.fmu.variables import ARRAYS

N_VALUES = (1, 3, 10, 50)
RECORDED = [b for b in ARRAYS if b.causality in ("output", "calculatedParameter")]


def build_times() -> tuple[float, float]:
    """Seconds for one forced FMI 3.0 build and one forced FMI 2.0 build (n = 3)."""
    old = os.environ.get("PUSHTRAIN_CACHE")
    with tempfile.TemporaryDirectory() as cache:
        os.environ["PUSHTRAIN_CACHE"] = cache
        try:
            start = time.perf_counter()
            build_fmu(fmi_version=3, force=True)
            t3 = time.perf_counter() - start
            start = time.perf_counter()
            build_fmu(3, force=True)
            t2 = time.perf_counter() - start
        finally:
            if old is None:
                del os.environ["PUSHTRAIN_CACHE"]
            else:
                os.environ["PUSHTRAIN_CACHE"] = old
    return t3, t2


def _inputs(stop: float) -> np.ndarray:
    t = np.arange(0.0, stop + 1e-9, 0.005)
    signals = np.zeros(t.size, dtype=[("time", float), ("v_cmd", float), ("w_cmd", float),
                                      ("push_x", float), ("push_y", float)])
    signals["time"], signals["v_cmd"] = t, -0.1 * np.cos(0.3 * t)
    signals["w_cmd"], signals["push_x"] = 0.4 * np.sin(0.7 * t), 30.0 * np.sin(t)
    signals["push_y"] = np.where(np.floor(t / 1.5) % 2, 60.0, -60.0)
    return signals


def agreement(fmu3: Path, n: int, slip_mode: int, stop: float = 10.0) -> tuple[float, bool]:
    """Largest |FMI 3.0 - FMI 2.0| over every output, sample and element; bit-identical?"""
    common = dict(stop_time=stop, output_interval=0.005, step_size=0.005, input=_inputs(stop))
    names2 = [f"{b.name}[{b.first + k}]" for b in RECORDED for k in range(b.count(n))]
    with contextlib.redirect_stdout(io.StringIO()):  # fmpy: "missing input for slide"
        r3 = simulate_fmu(str(fmu3), model_description=model_description_for(fmu3, n),
                          start_values={"n": n, "slip_mode": slip_mode},
                          output=[b.name for b in RECORDED], **common)
        r2 = simulate_fmu(str(build_fmu(n)), start_values={"slip_mode": slip_mode},
                          output=names2, **common)
    a = np.concatenate([np.asarray(r3[b.name], float).reshape(len(r3), -1) for b in RECORDED],
                       axis=1)
    b = np.column_stack([np.asarray(r2[name], float) for name in names2])
    return float(np.max(np.abs(a - b))), bool(np.array_equal(a, b))


def fmusim_check(fmusim: str, fmu3: Path, n: int, stop: float = 5.0) -> float:
    """Largest |fmusim - fmpy| of x, theta and F_lat for constant inputs."""
    start = {"n": n, "v_cmd": -0.08, "w_cmd": 0.2, "push_y": 20.0}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out.csv"
        command = [fmusim, "--interface-type", "cs", "--output-interval", "0.005",
                   "--stop-time", str(stop), "--output-file", str(out)]
        for name, value in start.items():
            command += ["--start-value", name, str(value)]
        subprocess.run(command + [str(fmu3)], check=True, capture_output=True, text=True)
        with out.open() as f:
            rows = list(csv.DictReader(f))
    ref = simulate_fmu(str(fmu3), model_description=model_description_for(fmu3, n),
                       start_values=start, stop_time=stop, output_interval=0.005,
                       step_size=0.005, output=["x", "theta", "F_lat"])
    assert len(rows) == len(ref), (len(rows), len(ref))
    worst = 0.0
    for name in ("x", "theta", "F_lat"):
        got = np.array([[float(v) for v in row[name].split()] for row in rows])
        worst = max(worst, float(np.max(np.abs(got - np.asarray(ref[name], float)))))
    return worst


def ecos_check(fmu3: Path, steps: int = 2000) -> str:
    """ecos at the default n = 3 through the scalars: the step where the train jackknifes."""
    try:
        from ecospy import EcosSimulation, EcosSimulationStructure
    except ImportError as exc:
        return f"ecospy not importable ({exc}): pip install ecospy==0.7.2 (needs libtbb12)"
    start = {"v_cmd": -0.1, "w_cmd": 0.8}
    structure = EcosSimulationStructure()
    structure.add_model("tt", str(fmu3))
    structure.add_parameter_set("start", {f"tt::{k}": v for k, v in start.items()})
    ecos_step = None
    with EcosSimulation(structure=structure, step_size=0.005) as sim:
        sim.init(parameter_set="start")
        for k in range(1, steps + 1):
            sim.step()
            if ecos_step is None and sim.get_bool("tt::jackknifed"):
                ecos_step = k
        t_end = sim.get_real("tt::time")
        sim.terminate()
    ref = simulate_fmu(str(fmu3), start_values=start, stop_time=steps * 0.005,
                       output_interval=0.005, step_size=0.005, output=["jackknifed"])
    fmpy_step = int(np.argmax(ref["jackknifed"])) if np.any(ref["jackknifed"]) else None
    verdict = "equal" if ecos_step == fmpy_step and ecos_step is not None else "DIFFERENT"
    return (f"ecos stepped to t = {t_end:.3f} s; jackknifed at step {ecos_step} "
            f"(fmpy: {fmpy_step}): {verdict}; arrays and n != 3 are out of ecos 0.7.2's reach")


def master_step_cost(fmu: Path, n: int, steps: int = 5000) -> float:
    """Microseconds per step of the master's wrapper calls: 2 reads, flags, commands, doStep."""
    with TrailerTrainSlave(fmu, n_trailers=n) as slave:
        slave.start({})
        read = slave.real_reader(
            slave.names("x", 0, n) + slave.names("y", 0, n) + slave.names("theta", 0, n)
            + slave.names("v", 0, n) + slave.names("w", 0, n) + slave.names("phi", 1, n)
            + slave.names("F_lat", 1, n) + slave.names("slide_speed", 1, n))
        flags = slave.bool_reader(slave.names("slipping", 1, n) + ["jackknifed"])
        write = slave.real_writer(["v_cmd", "w_cmd", "push_x", "push_y"])
        start = time.perf_counter()
        for k in range(steps):
            read()
            write((-0.05, 0.1 * math.sin(0.01 * k), 0.0, 0.0))
            read()
            flags()
            slave.do_step(k * 0.005, 0.005)
        return (time.perf_counter() - start) / steps * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fmusim", metavar="PATH", help="fmusim binary (RECIPES.md section 1)")
    parser.add_argument("--skip-build-time", action="store_true")
    args = parser.parse_args()

    if not args.skip_build_time:
        t3, t2 = build_times()
        print(f"build: FMI 3.0 (every n) {t3:.1f} s, one FMI 2.0 build (n = 3) {t2:.1f} s")
    fmu3 = Path(build_fmu(fmi_version=3))
    for n in N_VALUES:
        for mode in (0, 1):
            worst, identical = agreement(fmu3, n, mode)
            print(f"agreement n = {n:2d}, slip_mode {mode}: max |FMI3 - FMI2| = {worst:.3g}"
                  f"{' (bit-identical)' if identical else ''}")
    if args.fmusim:
        for n in N_VALUES:
            worst = fmusim_check(args.fmusim, fmu3, n)
            print(f"fmusim n = {n:2d}: max |fmusim - fmpy| = {worst:.3g}")
    else:
        print("fmusim: skipped (no --fmusim PATH; see this file's docstring to build it)")
    print(ecos_check(fmu3))
    for n in (3, 50):
        cost2, cost3 = master_step_cost(build_fmu(n), n), master_step_cost(fmu3, n)
        print(f"master wrapper per step, n = {n:2d}: FMI 2.0 {cost2:.1f} us, "
              f"FMI 3.0 {cost3:.1f} us")


if __name__ == "__main__":
    main()
