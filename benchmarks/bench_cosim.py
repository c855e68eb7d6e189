"""Closed-loop master against a raw-ctypes loop with the same FMI I/O (issue 14's benchmark).

For n = 3 and n = 50, in one process, on the same FMI 2.0 FMU:

(a) master
    :func:`pushtrain.cosim.master.simulate` tracking an arc backward (check_goal off, so every
    run takes the same number of steps): events, sensors, reference, controller, recorder, FMU.
    Judged: the master's one step loop (many steps per C call, ``cosim/csrc/master_loop.c``)
    with the compiled control law. Side by side: the same loop calling back the tests' readable
    Python law each step (``tests/reference/controller.py``, passed in built: the path of a law
    written in Python); both must give the same run bit for bit.
(b) raw
    a loop of bare ctypes calls on the FMU's own functions with preallocated value-reference and
    value arrays, doing per step the FMI calls the master does: ``fmi2GetReal`` of the states
    the controller measures (robot pose, last trailer pose, joint angles), ``fmi2SetReal`` of
    v_cmd, w_cmd, push_x, push_y (replaying the master's recorded commands, so the FMU does the
    same model work), ``fmi2GetReal`` of every output the master records, ``fmi2GetBoolean`` of
    the slip and jackknife flags, ``fmi2DoStep``. Its last outputs must equal the master's last
    row bit for bit (checked and printed).

Each is timed ``--repeats`` times, alternating, in CPU time of this process (the machine is
shared: wall time would count other processes' turns); the medians of microseconds per 5 ms step
and their ratio master / raw (the number judged; target <= 1.5) are printed. The master's time
is the whole :func:`simulate` call (set-up, loop, result table) over its steps; a warm-up run
first reads and extracts the FMU in this process (as for a sweep's later runs). Also printed:
the control law's share of the masters, C and Python (the tracking loop replayed
alone on the master's measurements; it must give the master's commands bit for bit), what those
masters cost without it, and the raw loop's getter share (the raw loop without its three
gets). ``--profile`` adds a cProfile of one master run per n (top functions by own time).

(c) open loop, n = 3
    the rotation of ``examples/rotation_slip.toml`` (a :class:`RotationProfile`, no reference,
    32 s): the master with the profile's table evaluated in C each step (what every open-loop
    run does), side by side with the same profile called back through the loop's Python hook
    (the profile behind an object without its table: the path open-loop runs took before); both
    must give the same run bit for bit, and the raw loop replaying the run's commands is the
    floor. Printed: us per step of each and their ratios to raw.

Run: python benchmarks/bench_cosim.py [--repeats 5] [--profile] [--n 3 50] [--no-open-loop]
"""

from __future__ import annotations

import argparse
import cProfile
import ctypes
import math
import pstats
import shutil
import statistics
import sys
import tempfile
import time
from ctypes import c_double, c_int, c_size_t, c_uint, c_void_p
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from pushtrain.core.controller import Controller, ControllerConfig
from pushtrain.core.openloop import RotationProfile
from pushtrain.core.reference import Reference
from pushtrain.core.segment import Segment
from pushtrain.core.sensors import Measurement
from pushtrain.core.tracking import TrackingLoop
from pushtrain.cosim.master import simulate
from pushtrain.cosim.plant import InitialState, PlantConfig
from pushtrain.fmu.build import build_fmu

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from reference.controller import BackwardController  # noqa: E402  (the tests' reference law)

STEP = 0.005  # [s]
HORIZON = {3: 60.0, 50: 20.0}  # [s] per run: 12,000 and 4,000 steps


def mission(n: int):
    """Reference (an 8 m arc of radius 2.5 m pushed backward at 0.08 m/s) and controller."""
    ref = Reference.from_segments((0.0, 0.0, math.pi), [Segment("arc", 8.0, 0.4)], speed=0.08)
    return ref, ControllerConfig.uniform(n)


MASTERS = {  # label -> controller class, or None for the ControllerConfig
    "C law": None,
    "Py law": BackwardController,
}
"""The masters timed: the compiled law (judged), the Python law called back from the loop."""


def run_master(fmu, n: int, horizon: float, label: str = "C law"):
    """(microseconds per step, Result) of one :func:`simulate` run of master ``label``."""
    ref, cfg = mission(n)
    law = MASTERS[label]
    start = time.process_time()
    result = simulate(fmu, ref, cfg if law is None else law(cfg), horizon=horizon,
                      check_goal=False, progress=False)
    wall = time.process_time() - start
    if not result.ok:
        raise SystemExit(f"master run n = {n} ended early: {result.status}: {result.message}")
    return wall / (len(result.data) - 1) * 1e6, result


def _names(n: int) -> tuple[list[str], list[str], list[str]]:
    """Names the master moves per step: measured states, recorded outputs, flags."""
    states = ["x[0]", "y[0]", "theta[0]", f"x[{n}]", f"y[{n}]", f"theta[{n}]"]
    states += [f"phi[{i}]" for i in range(1, n + 1)]
    outputs = [f"{b}[{i}]" for b in ("x", "y", "theta", "v", "w") for i in range(n + 1)]
    outputs += [f"{b}[{i}]" for b in ("phi", "F_lat", "slide_speed") for i in range(1, n + 1)]
    flags = [f"slipping[{i}]" for i in range(1, n + 1)] + ["jackknifed"]
    return states, outputs, flags


class RawLoop:
    """The FMU loaded by fmpy, stepped through bare ctypes calls (no argument conversion)."""

    def __init__(self, fmu, n: int):
        self.n = n
        md = read_model_description(str(fmu))
        self.unzip = tempfile.mkdtemp(prefix="bench-raw-")
        extract(str(fmu), self.unzip)
        self.slave = FMU2Slave(guid=md.guid, unzipDirectory=self.unzip,
                               modelIdentifier=md.coSimulation.modelIdentifier,
                               instanceName="raw")
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.types = {v.name: v.type for v in md.modelVariables}
        self.slave.instantiate()

    def start(self, start_values: dict, t0: float) -> None:
        """Set the plant's parameters and initial state, each with the setter of its type (the
        plant's start values hold Reals and the Integer ``slip_mode``)."""
        s = self.slave
        s.setupExperiment(startTime=t0)
        for name, value in start_values.items():
            kind = self.types[name]
            if kind == "Integer":
                s.setInteger([self.vr[name]], [int(value)])
            elif kind == "Boolean":
                s.setBoolean([self.vr[name]], [bool(value)])
            else:
                s.setReal([self.vr[name]], [float(value)])
        s.enterInitializationMode()
        s.exitInitializationMode()

    def _fn(self, name: str):
        address = ctypes.cast(getattr(self.slave.dll, name), c_void_p).value
        return ctypes.CFUNCTYPE(c_int)(address)

    def _prepare(self, inputs: np.ndarray) -> SimpleNamespace:
        """Every ctypes argument of the loop, built before it runs."""
        states, outputs, flags = _names(self.n)
        vr = self.vr
        rows = np.ascontiguousarray(inputs, dtype=float)
        return SimpleNamespace(
            comp=c_void_p(self.slave.component), rows=rows,
            state_vr=(c_uint * len(states))(*[vr[k] for k in states]),
            out_vr=(c_uint * len(outputs))(*[vr[k] for k in outputs]),
            flag_vr=(c_uint * len(flags))(*[vr[k] for k in flags]),
            in_vr=(c_uint * 4)(*[vr[k] for k in ("v_cmd", "w_cmd", "push_x", "push_y")]),
            state_buf=(c_double * len(states))(), out_buf=(c_double * len(outputs))(),
            flag_buf=(c_int * len(flags))(),
            n_state=c_size_t(len(states)), n_out=c_size_t(len(outputs)),
            n_flag=c_size_t(len(flags)), n_in=c_size_t(4),
            in_rows=[(c_double * 4).from_buffer(rows, 32 * k) for k in range(len(rows))],
            get_real=self._fn("fmi2GetReal"), set_real=self._fn("fmi2SetReal"),
            get_bool=self._fn("fmi2GetBoolean"), do_step=self._fn("fmi2DoStep"),
            h=c_double(STEP), true=c_int(1))

    def run(self, inputs: np.ndarray, t0: float) -> tuple[float, np.ndarray]:
        """Replay ``inputs`` (rows of v_cmd, w_cmd, push_x, push_y); (us per step, last outputs).

        The loop body is written out with local names: the floor the master is compared with."""
        a = self._prepare(inputs)
        comp, in_rows, h, true = a.comp, a.in_rows, a.h, a.true
        get_real, set_real, get_bool, do_step = a.get_real, a.set_real, a.get_bool, a.do_step
        state_vr, n_state, state_buf = a.state_vr, a.n_state, a.state_buf
        out_vr, n_out, out_buf = a.out_vr, a.n_out, a.out_buf
        flag_vr, n_flag, flag_buf = a.flag_vr, a.n_flag, a.flag_buf
        in_vr, n_in = a.in_vr, a.n_in
        last = len(in_rows) - 1
        start = time.process_time()
        for k in range(last + 1):
            status = get_real(comp, state_vr, n_state, state_buf)
            status |= set_real(comp, in_vr, n_in, in_rows[k])
            status |= get_real(comp, out_vr, n_out, out_buf)
            status |= get_bool(comp, flag_vr, n_flag, flag_buf)
            if k < last:
                status |= do_step(comp, c_double(t0 + k * STEP), h, true)
            if status > 1:
                raise SystemExit(f"raw loop: an FMI call failed at step {k} (status {status})")
        wall = time.process_time() - start
        return wall / last * 1e6, np.array(out_buf)

    def run_without_gets(self, inputs: np.ndarray, t0: float) -> float:
        """The raw loop with its set and doStep calls only: us per step (the rest of the raw
        loop's time is the three getters)."""
        a = self._prepare(inputs)
        comp, in_rows, h, true = a.comp, a.in_rows, a.h, a.true
        set_real, do_step, in_vr, n_in = a.set_real, a.do_step, a.in_vr, a.n_in
        last = len(in_rows) - 1
        start = time.process_time()
        for k in range(last + 1):
            status = set_real(comp, in_vr, n_in, in_rows[k])
            if k < last:
                status |= do_step(comp, c_double(t0 + k * STEP), h, true)
            if status > 1:
                raise SystemExit(f"raw loop: an FMI call failed at step {k} (status {status})")
        return (time.process_time() - start) / last * 1e6

    def close(self) -> None:
        self.slave.terminate()
        self.slave.freeInstance()
        shutil.rmtree(self.unzip, ignore_errors=True)


def run_raw(fmu, n: int, result, without_gets: bool = False, initial=None):
    """(us per step, whether its last outputs equal the master's last row) of the raw loop
    (from ``initial``, default the arc mission's start); with ``without_gets`` the us per step
    of its set and doStep calls alone instead."""
    plant = PlantConfig(n_trailers=n)
    if initial is None:
        initial = InitialState.behind_reference(mission(n)[0], plant.geometry())
    data = result.data
    raw = RawLoop(fmu, n)
    try:
        raw.start({**plant.start_values(), **initial.start_values()}, float(data["t"][0]))
        inputs = np.column_stack([data[k] for k in ("v_cmd", "w_cmd", "push_x", "push_y")])
        if without_gets:
            return raw.run_without_gets(inputs, float(data["t"][0]))
        us, last = raw.run(inputs, float(data["t"][0]))
    finally:
        raw.close()
    _, outputs, _ = _names(n)
    columns = [name.replace("slide_speed", "u").replace("[", "").replace("]", "")
               for name in outputs]
    expected = np.array([data[c][-1] for c in columns])
    return us, bool(np.array_equal(last, expected))


def control_law(n: int, result, implementation: str = "c") -> tuple[float, bool]:
    """(us per step, whether it gives the master's commands bit for bit) of the control law
    alone: the tracking loop (reference sample + controller) replayed on the master's measured
    states (perfect sensors), with the joint angles handed over as the master hands them."""
    ref, cfg = mission(n)
    data = result.data
    ctrl = {"c": Controller, "python": BackwardController}[implementation](cfg)
    step = float(data["t"][1] - data["t"][0])
    ctrl.reset(0.0, 0.0, float(data["t"][0]) - step)
    loop = TrackingLoop(ctrl, ref, info=False)  # as the master: no ControlInfo
    phi = np.column_stack([data[f"phi_meas{i}"] for i in range(1, n + 1)])
    measurements = [Measurement(x0, y0, th0, angles)
                    for x0, y0, th0, angles in zip(data["x0"].tolist(), data["y0"].tolist(),
                                                   data["theta0"].tolist(), phi.tolist(),
                                                   strict=True)]
    times = data["t"].tolist()
    commands = []
    start = time.process_time()
    for t, meas in zip(times, measurements, strict=True):
        commands.append(loop.command(t, meas)[:2])
    wall = time.process_time() - start
    same = np.array_equal(np.array(commands), np.column_stack([data["v_cmd"], data["w_cmd"]]))
    return wall / (len(times) - 1) * 1e6, same


def profile(fmu, n: int, horizon: float) -> None:
    prof = cProfile.Profile()
    prof.enable()
    run_master(fmu, n, horizon)
    prof.disable()
    print(f"\n--- cProfile of one master run, n = {n} (own time) ---")
    pstats.Stats(prof).sort_stats("tottime").print_stats(14)


ROTATION = dict(w_max=math.radians(10.0), alpha=math.radians(5.0))  # rotation_slip's swing
ROTATION_HORIZON = 32.0  # [s]: 6,400 steps


class HookedProfile:
    """A profile behind an object without its C table: the master calls its ``command`` back
    through the loop's Python hook each step."""

    def __init__(self, profile):
        self.n, self.guide_geometry, self.command = profile.n, None, profile.command


def run_open_loop(fmu, hooked: bool):
    """(us per step, Result) of the rotation's master run, the table in C or called back."""
    profile = RotationProfile(3, **ROTATION)
    controller = HookedProfile(profile) if hooked else profile
    initial = InitialState(0.0, 0.0, np.zeros(4))
    start = time.process_time()
    result = simulate(fmu, None, controller, initial=initial, horizon=ROTATION_HORIZON,
                      progress=False)
    wall = time.process_time() - start
    if not result.ok:
        raise SystemExit(f"open-loop run ended early: {result.status}: {result.message}")
    return wall / (len(result.data) - 1) * 1e6, result


def open_loop(repeats: int) -> None:
    """Section (c): the rotation profile in C against the same profile called back."""
    fmu = build_fmu(3)
    for hooked in (False, True):
        run_open_loop(fmu, hooked)  # warm-up
    times = {False: [], True: []}
    raws, same, equal = [], True, True
    for _ in range(repeats):
        results = {}
        for hooked in (False, True):
            us, results[hooked] = run_open_loop(fmu, hooked)
            times[hooked].append(us)
        same = same and results[False].data.tobytes() == results[True].data.tobytes()
        us_raw, ok = run_raw(fmu, 3, results[False],
                             initial=InitialState(0.0, 0.0, np.zeros(4)))
        raws.append(us_raw)
        equal = equal and ok
    r = statistics.median(raws)
    c, py = statistics.median(times[False]), statistics.median(times[True])
    print(f"open loop (rotation_slip's swing), n = 3, {len(results[False].data) - 1} steps, "
          f"medians of {repeats} (CPU time of this process):\n"
          f"  master, profile table in C   {c:7.2f} us/step: {c / r:.2f}x raw ({r:.2f} us/step)\n"
          f"  master, profile called back  {py:7.2f} us/step: {py / r:.2f}x raw; "
          f"called back / C = {py / c:.2f}x\n"
          f"  the two runs bit-identical: {same}; raw loop reproduces the outputs: {equal}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--n", type=int, nargs="+", default=[3, 50])
    parser.add_argument("--profile", action="store_true")
    parser.add_argument("--no-open-loop", action="store_true", help="skip section (c)")
    args = parser.parse_args()
    ratios = {}
    for n in args.n:
        fmu = build_fmu(n)
        horizon = HORIZON.get(n, 20.0)
        for label in MASTERS:  # warm-up: imports, caches, the C library
            run_master(fmu, n, horizon, label)
        masters = {label: [] for label in MASTERS}
        laws = {impl: [] for impl in ("c", "python")}
        raws, same, same_law, same_runs = [], True, True, True
        for _ in range(args.repeats):
            results = {}
            for label in MASTERS:
                us, results[label] = run_master(fmu, n, horizon, label)
                masters[label].append(us)
            result = results["C law"]
            same_runs = same_runs and all(
                np.array_equal(result.data[k], other.data[k], equal_nan=True)
                for other in results.values() for k in result.data.dtype.names)
            us_raw, equal = run_raw(fmu, n, result)
            raws.append(us_raw)
            same = same and equal
            for impl, label in (("c", "C law"), ("python", "Py law")):
                us_law, equal_law = control_law(n, results[label], impl)
                laws[impl].append(us_law)
                same_law = same_law and equal_law
        r = statistics.median(raws)
        ratios[n] = {label: statistics.median(masters[label]) / r for label in MASTERS}
        print(f"n = {n:2d}, {len(result.data) - 1} steps, medians of {args.repeats} "
              "(CPU time of this process):")
        for label in MASTERS:
            m = statistics.median(masters[label])
            judged = "judged; " if label == "C law" else ""
            print(f"  master ({label:7s}) {m:7.2f} us/step, raw ctypes {r:6.2f} us/step: "
                  f"RATIO master/raw = {m / r:.2f}x ({judged}target <= 1.5x; of the fastest "
                  f"runs {min(masters[label]):.2f} / {min(raws):.2f} = "
                  f"{min(masters[label]) / min(raws):.2f}x)")
        for impl, label in (("c", "C law"), ("python", "Py law")):
            m, c = statistics.median(masters[label]), statistics.median(laws[impl])
            print(f"    control law ({impl}: reference + controller, replayed alone) {c:.2f} "
                  f"us/step = {100 * c / m:.0f} % of the {label} master; the rest "
                  f"{m - c:.2f} us/step = {(m - c) / r:.2f}x raw")
        print(f"  the masters' runs bit-identical: {same_runs}\n"
              f"  raw loop reproduces the master's outputs bit for bit: {same}; "
              f"replayed control laws their masters' commands: {same_law}")
        bare = statistics.median(run_raw(fmu, n, result, without_gets=True)
                                 for _ in range(args.repeats))
        print(f"  of the raw loop's time, the three FMU getters {r - bare:.2f} us/step, "
              f"set + doStep {bare:.2f} us/step")
        if args.profile:
            profile(fmu, n, horizon)
    if not args.no_open_loop:
        open_loop(args.repeats)
    print("RATIO master/raw, " + "; ".join(
        f"n = {n}: {ratios[n]['C law']:.2f}x (Python law {ratios[n]['Py law']:.2f}x)"
        for n in ratios) + " -- judged: the compiled law, target <= 1.5x")


if __name__ == "__main__":
    main()
