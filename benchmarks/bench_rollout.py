"""The closed-loop engine vs the readable Python loop it is held equal to (issue 13's >= 20x).

Runs the same plan (a bay plan like examples/bay.toml's: pull 4.5 m, cusp, push around a 1.7 m
arc and 2.1 m into the bay; settle 2 s; step 0.025 s) through the tests' Python reference loop
(``tests/reference/closed_loop.py`` ``simulate_tracking``) and the engine,
:func:`pushtrain.core.engine.simulate` (C), in the same process, for n = 3 and n = 10, and
prints simulated seconds per wall second of each and their ratio (best of several repeats, so a
busy machine slows both alike). Also checks that both give the same states.

Run: python benchmarks/bench_rollout.py [--repeat R]
"""

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.engine import ClosedLoopEngine, simulate
from pushtrain.core.kinematics import ChainGeometry
from pushtrain.core.reference import Reference
from pushtrain.core.segment import PULL, PUSH, Segment
from pushtrain.defaults import ROLLOUT_SETTLE_TIME, ROLLOUT_STEP

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from reference.closed_loop import simulate_tracking  # noqa: E402  (the tests' reference loop)

STEP = ROLLOUT_STEP
SETTLE = ROLLOUT_SETTLE_TIME


def bay_reference() -> Reference:
    segments = [Segment("line", 4.5, 0.0, PULL), Segment("arc", 0.5 * math.pi * 1.7, 1 / 1.7, PUSH),
                Segment("line", 2.1, 0.0, PUSH)]
    return Reference.from_segments((11.5, 1.5, math.pi), segments, 0.08, 1.0)


def best_of(repeat: int, run) -> float:
    best = math.inf
    for _ in range(repeat):
        start = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - start)
    return best


def main(repeat: int) -> None:
    ref = bay_reference()
    simulated = math.ceil((ref.t_end + SETTLE) / STEP - 1e-9) * STEP
    print(f"plan: {len(ref.segments)} segments, {ref.length:.2f} m, {simulated:.1f} s simulated "
          f"at step {STEP} s ({round(simulated / STEP)} steps)")
    for n in (3, 10):
        geom = ChainGeometry.uniform(n, 0.52)
        config = ControllerConfig(geometry=geom)
        heads = np.full(n + 1, math.pi)
        py = simulate_tracking(geom, ref, heads, config, STEP, SETTLE)
        c = simulate(geom, ref, heads, config, STEP, SETTLE)
        diff = float(np.abs(c.states - py.state).max())
        t_py = best_of(max(1, repeat // 3), lambda g=geom, cf=config, h=heads:
                       simulate_tracking(g, ref, h, cf, STEP, SETTLE))
        t_c = best_of(repeat, lambda g=geom, cf=config, h=heads:
                      simulate(g, ref, h, cf, STEP, SETTLE))
        # the planner's edge cost: the loop only (reference table and pull guide prepared)
        loop = ClosedLoopEngine(geom, config, STEP)
        state = loop.start(ref.start, heads)
        k_end = loop.instant_at(ref.t_end + SETTLE)
        loop.run(ref, state, k_end)
        t_loop = best_of(repeat, lambda lp=loop, s=state, k=k_end: lp.run(ref, s, k,
                                                                          record=False))
        print(f"n = {n:2d}: Python reference {simulated / t_py:9,.0f} sim-s/s "
              f"({t_py * 1e3:8.1f} ms) | C rollout {simulated / t_c:11,.0f} sim-s/s "
              f"({t_c * 1e3:6.2f} ms) | ratio {t_py / t_c:6.0f}x | loop only {t_py / t_loop:6.0f}x"
              f" | max state difference {diff:.1e}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=9, help="repeats (best of) per timing")
    main(parser.parse_args().repeat)
