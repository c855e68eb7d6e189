"""Planning on an occupancy grid against the same geometry as polygons (issue 15).

Usage: python benchmarks/bench_maps.py [--seeds 3] [--resolution 0.05] [--budget 5.0] [--prep-only]

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

First, preparing a map (issue 34 item 6): a 50 m x 30 m depot rendered at 3 cm and at 5 cm,
prepared as the planner does before its search (reading the files; the World: traced
polygons, free space and distance field, from the map cache when there; the "impossible
here" labelling; the heuristic's grid Dijkstra) and then the route graph the search asks for,
with an empty cache (cold) and again from the cache (warm), in CPU seconds of this process,
side by side, against the targets: cold <= 1 s with the route, warm <= 0.3 s to the search.
Then the time to the answer "impossible here" on two public maps.
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


def depot(resolution: float, folder: Path) -> Path:
    """A 50 m x 30 m depot (two blocks of six rack rows, a cross aisle, a box turned by 30
    deg) rendered into a map_server map at ``resolution`` [m]; the YAML's path."""
    obstacles = [box(3.0, y0, 22.0, y0 + 1.2) for y0 in 3.0 + 4.0 * np.arange(6)]
    obstacles += [box(26.0, y0, 47.0, y0 + 1.2) for y0 in 3.0 + 4.0 * np.arange(6)]
    obstacles.append(rotate(box(23.0, 14.0, 25.0, 15.0), 30.0))
    world = World(box(0.0, 0.0, 50.0, 30.0), tuple(obstacles))
    nx, ny = int(round(50.0 / resolution)), int(round(30.0 / resolution))
    cx, cy = (np.arange(nx) + 0.5) * resolution, (np.arange(ny) + 0.5) * resolution
    free = shapely.contains_xy(world.free, cx[None, :], cy[::-1, None])
    Image.fromarray(np.where(free, 254, 0).astype(np.uint8)).save(folder / "depot.pgm")
    yaml = folder / "depot.yaml"
    yaml.write_text(f"image: depot.pgm\nresolution: {resolution}\norigin: [0.0, 0.0, 0.0]\n"
                    "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return yaml


def prepare(yaml: Path) -> dict:
    """CPU seconds of each step the planner takes on ``yaml`` before and at its search's
    start (the defaults: PlannerConfig(), three trailers), from one corner to the other."""
    from pushtrain.planner.heuristic import Heuristic
    from pushtrain.planner.passage import needed_half_width, passable
    from pushtrain.planner.route import find_route
    from pushtrain.planner.whole_train import HEURISTIC_NODES_PER_SECOND

    config, train = PlannerConfig(), Train.uniform(3)
    start, goal = (1.5, 2.0, math.pi), (48.5, 28.0, 0.5 * math.pi)
    half = needed_half_width(train, config.margins(train)[-1])
    steps, t = {}, time.process_time()

    def step(name):
        nonlocal t
        now = time.process_time()
        steps[name], t = now - t, now

    grid = load_map(yaml)
    step("read")
    field = grid_world(grid).distance_field()
    step("world")
    assert passable(field, start, goal, half)
    step("impossible?")
    Heuristic(field, goal, config.radius_for(train), half, build_car=False,
              max_nodes=int(HEURISTIC_NODES_PER_SECOND * 0.25 * config.budget_seconds()))
    step("heuristic")
    steps["to search"] = sum(steps.values())
    assert find_route(field, start, goal, 0.5 * train.last.width + config.margins(train)[-1])
    step("route")
    steps["with route"] = steps["to search"] + steps["route"]
    return steps


def preparation() -> None:
    """Print cold and warm preparation of the depot at 3 cm and 5 cm, side by side."""
    import os

    from scipy import ndimage

    ndimage.label(np.ones((2, 2)))  # the first call's imports are the process's, not the map's
    print("preparing a 50 m x 30 m map (CPU s of this process, imports done; cold: empty map "
          "cache, warm: the same map again)")
    for resolution in (0.03, 0.05):
        with tempfile.TemporaryDirectory() as tmp:
            os.environ["PUSHTRAIN_CACHE"] = str(Path(tmp) / "cache")
            yaml = depot(resolution, Path(tmp))
            cold, warm = prepare(yaml), prepare(yaml)
        names = list(cold)
        print(f"  {resolution * 100:.0f} cm ({int(50 / resolution)} x {int(30 / resolution)} "
              "cells): " + ", ".join(f"{k} {cold[k]:.3f}/{warm[k]:.3f}" for k in names))
        print(f"    cold with route {cold['with route']:.2f} s (target <= 1 s: "
              f"{'met' if cold['with route'] <= 1.0 else 'NOT met'}); warm to search "
              f"{warm['to search']:.2f} s (target <= 0.3 s: "
              f"{'met' if warm['to search'] <= 0.3 else 'NOT met'})")
    os.environ.pop("PUSHTRAIN_CACHE", None)


PUBLIC = Path(__file__).resolve().parents[1] / "examples" / "maps" / "public"
IMPOSSIBLE = {  # roomy places whose every way narrows below 1.5 m (tests/planner/test_passage.py
    # finds such pairs with its own maximin over scipy's distance transform)
    "aws_bookstore": ((-0.47, -0.82, 157.5), (-3.02, 5.73, -22.5)),
    "willow_garage": ((38.85, 18.65, 157.5), (10.25, 46.75, 0.0)),
}


def impossible() -> None:
    """Print the CPU seconds to the answer "impossible here" (reading the map included) for a
    trailer that asks 0.45 m of clearance (1.5 m passages) on two public maps."""
    from pushtrain.facility.loading import map_world

    times = []
    for name, (start, goal) in IMPOSSIBLE.items():
        t = time.process_time()
        world = map_world(grid=str(PUBLIC / f"{name}.yaml"))
        try:
            plan(world, (*start[:2], math.radians(start[2])), (*goal[:2], math.radians(goal[2])),
                 Train.uniform(1), PlannerConfig(clearance=[0.05, 0.45]))
            answer = "planned (not impossible!)"
        except PlanningError as exc:
            answer = "impossible here" if exc.details.get("impossible") else exc.reason
        times.append(f"{name} {time.process_time() - t:.3f} s ({answer})")
    print("answer for a way too narrow (CPU s, map read included): " + ", ".join(times))


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
    parser.add_argument("--prep-only", action="store_true",
                        help="only the map preparation (cold vs warm)")
    args = parser.parse_args(argv)
    preparation()
    impossible()
    if args.prep_only:
        return
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
