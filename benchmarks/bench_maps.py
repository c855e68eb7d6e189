"""Planning on an occupancy grid against the same geometry as polygons (issue 15).

Usage: python benchmarks/bench_maps.py [--seeds 3] [--resolution 0.05] [--budget 5.0]

A 100 m x 100 m hall with rack rows, a cross aisle and a few boxes turned by 30 deg is given
twice: as polygons (a World built from them), and rendered into a map_server map (PGM + YAML,
a pixel free when its centre is in the free space; 2000 x 2000 pixels at 5 cm) that is loaded
with ``pushtrain.facility.map_server.load_map`` and turned into a World (``grid_world``). The
same planner (whatever ``pushtrain.planner.planner.plan`` is in this checkout; it is named in the
output)
plans the same mission on both with the same seeds, and the script prints, side by side:

- building the world (polygons: the World; grid: reading the files, tracing the polygons);
- planning (``plan``, train check included);
- the total, and the ratio grid / polygons judged against the target of 2.0;
- path lengths, so that a fast but different answer shows.
"""

from __future__ import annotations

import argparse
import math
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
import shapely
from PIL import Image
from shapely.affinity import rotate
from shapely.geometry import box

from pushtrain.errors import PlanningError
from pushtrain.facility.free_space import World
from pushtrain.facility.loading import grid_world
from pushtrain.facility.map_server import load_map
from pushtrain.planner.config import PlannerConfig
from pushtrain.planner.planner import plan
from pushtrain.planner.train import Train

SIZE = 100.0                                     # m
START = (6.0, 42.95, math.pi)                    # last trailer, pushed toward +x (an aisle)
GOAL = (42.5, 55.0, -0.5 * math.pi)               # pushed toward +y, in the cross aisle


def hall() -> World:
    """The polygon world: rack rows along x with a cross aisle at x = 40..45 m, boxes at 30 deg."""
    obstacles = []
    for k in range(12):
        y0 = 8.0 + 7.5 * k
        obstacles += [box(4.0, y0, 40.0, y0 + 2.4), box(45.0, y0, 96.0, y0 + 2.4)]
    for cx, cy in ((20.0, 44.25), (70.0, 51.75), (30.0, 74.25), (80.0, 21.75)):
        obstacles.append(rotate(box(cx - 1.0, cy - 0.5, cx + 1.0, cy + 0.5), 30.0))
    return World(box(0.0, 0.0, SIZE, SIZE), tuple(obstacles))


def write_map(world: World, folder: Path, resolution: float) -> Path:
    """Render ``world`` into a map_server map in ``folder``; the YAML's path."""
    n = int(round(SIZE / resolution))
    centres = (np.arange(n) + 0.5) * resolution
    free = shapely.contains_xy(world.free, centres[None, :], centres[::-1, None])  # row 0 top
    Image.fromarray(np.where(free, 254, 0).astype(np.uint8)).save(folder / "hall.pgm")
    yaml = folder / "hall.yaml"
    yaml.write_text(f"image: hall.pgm\nresolution: {resolution}\norigin: [0.0, 0.0, 0.0]\n"
                    "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return yaml


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def plan_once(world, seed: int, budget: float):
    cfg = PlannerConfig(seed=seed, time_budget=budget)
    try:
        return plan(world, START, GOAL, Train.uniform(3), cfg)
    except PlanningError as exc:
        return exc


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--resolution", type=float, default=0.05)
    parser.add_argument("--budget", type=float, default=5.0)
    args = parser.parse_args(argv)
    print(f"planner: {plan.__module__}.{plan.__name__} (this checkout), seeds 1..{args.seeds}, "
          f"time_budget {args.budget} s")
    with tempfile.TemporaryDirectory() as tmp:
        polygons, t_poly_build = timed(hall)
        yaml = write_map(polygons, Path(tmp), args.resolution)
        grid, t_load = timed(lambda: load_map(yaml))
        gridded, t_trace = timed(lambda: grid_world(grid))
    ny, nx = grid.shape
    print(f"map: {nx} x {ny} cells at {args.resolution} m; polygon world built in "
          f"{t_poly_build:.3f} s; grid read in {t_load:.3f} s, traced into a World in "
          f"{t_trace:.3f} s")
    rows = []
    for seed in range(1, args.seeds + 1):
        a, ta = timed(lambda seed=seed: plan_once(polygons, seed, args.budget))
        b, tb = timed(lambda seed=seed: plan_once(gridded, seed, args.budget))
        rows.append((seed, ta, tb, a, b))
        print(f"  seed {seed}: polygons {ta:6.2f} s ({_result(a)}), grid {tb:6.2f} s "
              f"({_result(b)})")
    poly_total = t_poly_build + sum(r[1] for r in rows)
    grid_total = t_load + t_trace + sum(r[2] for r in rows)
    med_a = statistics.median(r[1] for r in rows)
    med_b = statistics.median(r[2] for r in rows)
    print(f"median plan time: polygons {med_a:.2f} s, grid {med_b:.2f} s "
          f"(ratio {med_b / med_a:.2f})")
    ratio = grid_total / poly_total
    print(f"total (build + {len(rows)} plans): polygons {poly_total:.2f} s, grid "
          f"{grid_total:.2f} s")
    print(f"ratio grid / polygons = {ratio:.2f} (target <= 2.0: "
          f"{'met' if ratio <= 2.0 else 'NOT met'})")


def _result(result) -> str:
    if isinstance(result, PlanningError):
        return f"failed: {result.reason}"
    return f"{result.length:.2f} m, {result.n_cusps} cusps"


if __name__ == "__main__":
    main()
