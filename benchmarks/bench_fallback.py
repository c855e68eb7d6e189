"""The planner with and without a C compiler: the compiled closed loop against the Python fallback.

Without a C compiler, :func:`pushtrain.planner.propagate.make_propagator` cannot build the
compiled closed loop (:class:`~pushtrain.planner.propagate.NativePropagator`), logs a warning
and plans with the Python :class:`~pushtrain.planner.propagate.Propagator`. This script plans
the same bundled examples both ways, in one process and alternately (C, Python, C, Python, ...),
so that both see the same machine and the same load, and prints the ratio of their times.

The fallback is reached the way a machine without a compiler reaches it: ``CC`` names a program
that does not exist and ``PUSHTRAIN_CACHE`` an empty folder (no library built before), so
:func:`pushtrain.core.native.load` raises ``NativeBuildError``; the C runs use the normal
setting (the library built once and cached, not timed). Each plan's ``info["propagator"]`` is
checked to be the one asked for.

The budget counts simulated control steps, not seconds, so both searches do about the same
work; the wall-clock safety cap is raised (``time_cap``) so that it cannot cut the slower search
short. They are not bit-identical (the compiled checks leave a body's interior points to the
exact test of the final path), so the expansions and steps of both are printed, and the ratio
per simulated step beside the ratio of the plan times. The time of a plan includes the
heuristic, the route and the exact test of the final path, which do not depend on the loop (the
map's distance field is built once per map before the clock starts).

Printed per example: the median wall time of each, their ratio (Python / C), the CPU-time
ratio, the ratio per simulated step, the ratio of the time spent in the rollouts alone (the
loop itself: ``Propagator.rollout`` against ``NativePropagator.rollout``, timed inside the same
plans), and the load average beside them; last, the ratios over all examples (total Python
time / total C time) and their range over the examples.

Run: python benchmarks/bench_fallback.py [--examples l_corridor,three_point_turn] [--repeats 3]
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import os
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_planner import _problem  # noqa: E402  (this folder, on the path above)

from pushtrain.core import native  # noqa: E402
from pushtrain.planner.planner import plan
from pushtrain.planner.propagate import NativePropagator, Propagator  # noqa: E402

DEFAULT = ("l_corridor", "bay", "docking", "three_point_turn", "narrow_l_5", "parallel_parking")
TIME_CAP = 3600.0  # [s]: the safety cap must not stop the slow search first


_IN_ROLLOUTS = [0.0]  # wall time [s] spent in the propagators' rollout() calls


def _timed_rollout(method):
    def rollout(self, *args, **kwargs):
        t0 = time.perf_counter()
        try:
            return method(self, *args, **kwargs)
        finally:
            _IN_ROLLOUTS[0] += time.perf_counter() - t0
    return rollout


for _cls in (Propagator, NativePropagator):  # each defines its own rollout (no nesting)
    _cls.rollout = _timed_rollout(_cls.__dict__["rollout"])


@contextlib.contextmanager
def no_compiler():
    """The environment of a machine without a C compiler (and no library built before)."""
    saved = {key: os.environ.get(key) for key in ("CC", "PUSHTRAIN_CACHE")}
    with tempfile.TemporaryDirectory() as empty:
        os.environ["CC"] = "/nonexistent/no-such-cc"
        os.environ["PUSHTRAIN_CACHE"] = empty
        try:
            yield
        finally:
            for key, value in saved.items():
                if value is None:
                    os.environ.pop(key, None)
                else:
                    os.environ[key] = value


def _plan(problem, python: bool) -> dict:
    _, world, train, start, goal, config, headings = problem
    config = replace(config, time_cap=TIME_CAP)
    with no_compiler() if python else contextlib.nullcontext():
        _IN_ROLLOUTS[0] = 0.0
        t0, c0 = time.perf_counter(), time.process_time()
        path = plan(world, start, goal, train, config, start_headings=headings)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        rollouts = _IN_ROLLOUTS[0]
    want = "Propagator" if python else "NativePropagator"
    if path.info["propagator"] != want:
        raise RuntimeError(f"asked for {want}, planned with {path.info['propagator']}")
    if path.info.get("time_capped"):
        raise RuntimeError("the safety cap stopped the search: the two runs differ")
    return {"wall": wall, "cpu": cpu, "rollouts": rollouts, "expansions": path.info["expansions"],
            "steps": path.info["steps"], "load": os.getloadavg()[0]}


def bench(name: str, repeats: int) -> dict:
    problem = _problem(name)
    problem[1].distance_field()  # built once per map, outside the clock
    native.load()  # the compiled loop is built once per machine (cached): not timed
    _plan(problem, python=False)  # warm-up
    runs = {"c": [], "python": []}
    for _ in range(repeats):
        for label in ("c", "python"):
            runs[label].append(_plan(problem, python=label == "python"))
    out = {"name": name}
    for label, rs in runs.items():
        work = {(r["expansions"], r["steps"]) for r in rs}
        if len(work) != 1:  # a plan is a function of the scenario: the clock must not matter
            raise RuntimeError(f"{name}, {label}: plans differ between runs: {sorted(work)}")
        expansions, steps = work.pop()
        out[label] = {key: statistics.median(r[key] for r in rs)
                      for key in ("wall", "cpu", "rollouts")}
        out[label].update(expansions=expansions, steps=steps)
    c, py = out["c"], out["python"]
    loads = [r["load"] for rs in runs.values() for r in rs]
    out.update(ratio=py["wall"] / c["wall"], cpu_ratio=py["cpu"] / c["cpu"],
               step_ratio=(py["wall"] / py["steps"]) / (c["wall"] / c["steps"]),
               rollout_ratio=(py["rollouts"] / py["steps"]) / (c["rollouts"] / c["steps"]),
               load=(min(loads), max(loads)))
    return out


def _once(record, seen=set()) -> bool:  # noqa: B006 - the set is the filter's memory
    """A logging filter: each message once (the fallback's warning, not once per plan)."""
    key = record.getMessage()
    if key in seen:
        return False
    seen.add(key)
    return True


def main() -> None:
    logging.getLogger("pushtrain.planner.propagate").addFilter(_once)
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--examples", default=",".join(DEFAULT))
    ap.add_argument("--repeats", type=int, default=3, help="plans of each kind per example")
    args = ap.parse_args()
    print(f"planner with the compiled closed loop (C) and with the Python fallback, "
          f"{args.repeats} plans each, alternating; {os.cpu_count()} cores, load average "
          f"{os.getloadavg()[0]:.2f} at the start")
    results = []
    for name in args.examples.split(","):
        r = bench(name.strip(), args.repeats)
        results.append(r)
        c, py = r["c"], r["python"]
        print(f"{r['name']:>17}: C {c['wall']:.3f} s ({c['expansions']} expansions, "
              f"{c['steps']} steps), Python {py['wall']:.3f} s ({py['expansions']} expansions, "
              f"{py['steps']} steps): {r['ratio']:.1f} x wall, {r['cpu_ratio']:.1f} x CPU, "
              f"{r['step_ratio']:.1f} x per step; rollouts alone C {c['rollouts']:.3f} s, "
              f"Python {py['rollouts']:.3f} s: {r['rollout_ratio']:.1f} x per step; load "
              f"{r['load'][0]:.2f}-{r['load'][1]:.2f}", flush=True)
    total_c = sum(r["c"]["wall"] for r in results)
    total_py = sum(r["python"]["wall"] for r in results)
    ratios = [r["ratio"] for r in results]
    lo = min(r["load"][0] for r in results)
    hi = max(r["load"][1] for r in results)
    roll_c = sum(r["c"]["rollouts"] for r in results)
    roll_py = sum(r["python"]["rollouts"] for r in results)
    roll = [r["rollout_ratio"] for r in results]
    print(f"all examples: plans C {total_c:.2f} s, Python {total_py:.2f} s: planning without "
          f"a compiler is {total_py / total_c:.1f} x slower (per example "
          f"{min(ratios):.1f}-{max(ratios):.1f} x; geometric mean "
          f"{math.exp(statistics.mean(math.log(x) for x in ratios)):.1f} x); the rollouts alone "
          f"C {roll_c:.2f} s, Python {roll_py:.2f} s: {roll_py / roll_c:.1f} x (per example "
          f"{min(roll):.1f}-{max(roll):.1f} x per step); load {lo:.2f}-{hi:.2f} on "
          f"{os.cpu_count()} cores")


if __name__ == "__main__":
    main()
