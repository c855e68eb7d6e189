"""Closed-loop co-simulation throughput for n = 3 (issue 3's benchmark).

Compares steps per second of :func:`pushtrain.cosim.master.simulate` (FMU + sensors + controller +
recorder) with bare fmpy ``doStep`` calls on the same FMU in the same run, and profiles the loop.
Target: >= 20,000 closed-loop steps/s and no more than 3x the bare step cost.

Run: python benchmarks/bench_cosim.py [--profile]
"""

import cProfile
import math
import pstats
import sys
import time

from bench_fmu import bench

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.reference import Reference, Segment
from pushtrain.cosim.master import simulate
from pushtrain.fmu import build_fmu


def closed_loop(profile: bool = False) -> float:
    fmu = build_fmu(3)
    ref = Reference.from_segments((0.0, 0.0, math.pi), [Segment("arc", 8.0, 0.4)], speed=0.08)
    cfg = ControllerConfig.uniform(3)
    if profile:
        prof = cProfile.Profile()
        prof.enable()
    start = time.perf_counter()
    result = simulate(fmu, ref, cfg, horizon=100.0, check_goal=False, progress=False)
    wall = time.perf_counter() - start
    if profile:
        prof.disable()
        pstats.Stats(prof).sort_stats("tottime").print_stats(12)
    return (len(result.data) - 1) / wall


if __name__ == "__main__":
    bare_us, _ = bench(3)
    rate = closed_loop("--profile" in sys.argv)
    print(f"bare fmpy doStep: {bare_us:.2f} us/step = {1e6 / bare_us:,.0f} steps/s")
    print(f"closed loop:      {1e6 / rate:.2f} us/step = {rate:,.0f} steps/s "
          f"({(1e6 / rate) / bare_us:.1f}x the bare step)")
