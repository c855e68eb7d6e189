"""Proofs that a facility mission is impossible, independent of the planner (issue 34 item 3).

Usage: python benchmarks/prove_impossible.py [--write]

For every mission of ``benchmarks/facility/missions.toml`` without a witness it tries the proof
below on the map's occupancy grid (scipy's ``distance_transform_edt`` and ``label``; no distance
field, route or search of the planner) and prints it; ``--write`` records the missions it proves
in ``benchmarks/facility/impossible.toml`` (atomically, the file's header kept).

The proof (no way of the last trailer's width)
    Wherever the last trailer goes, the disc of radius ``r`` round its axle midpoint (half its
    width, or less if its rectangle ends nearer, plus its clearance) lies in the free space.
    Take a point ``p`` of its way and the centre ``c`` of the grid cell holding it
    (``|p - c| <= h / sqrt 2``). A blocked cell (a square of side ``h``; outside the grid is
    blocked) whose centre is ``b`` holds the disc of radius ``h / 2`` round ``b``, so
    ``|c - b| >= dist(c, cell) + h / 2 >= r - h / sqrt 2 + h / 2``. Every cell the axle midpoint
    crosses is therefore at least ``need = r - 0.207 h`` from every blocked cell's centre (the
    Euclidean distance transform of the grid), and consecutive cells of a continuous way are
    8-neighbours. If the cells at ``need`` or more (8-connected) do not join the start's cell
    to the goal's, the train has no way: impossible, with that clearance, on this map.
The width named
    The widest way's narrowest place by the same transform: the largest ``m`` such that cells at
    ``m`` or more join start and goal (a maximin), at the cell of that level nearest to both
    sides it joins. A cell ``m`` from the nearest blocked centres on both sides lies in an
    opening ``2 m - h`` (centred) to ``2 m`` (one cell off centre) wide wall to wall:
    ``width = 2 m - h / 2``, within half a cell. The planner's "impossible here" must name that
    width within one cell (``bench_facility.py``, ``tests/benchmarks/test_impossible.py``).

Lengths in metres; a cell (i, j) of the grid is at ``(x0 + j h, y0 + i h)``.
"""

from __future__ import annotations

import argparse
import math
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

HERE = Path(__file__).resolve().parent
_EIGHT = np.ones((3, 3), dtype=bool)

HEADER = """\
# Missions of the facility benchmark shown impossible, each with its proof: computed by
# benchmarks/prove_impossible.py from the map's occupancy grid with scipy's
# distance_transform_edt, independently of the planner (issue 34 item 3; the proof is in that
# script's docstring). `width` [m] is the widest way's narrowest opening wall to wall (within
# half a cell), at `at` [x, y m]; `needed` [m] what the last trailer and its clearance need;
# `cell` [m] the map's cell. Written by `python benchmarks/prove_impossible.py --write`.
"""


@dataclass(frozen=True)
class Proof:
    """No way of the last trailer from ``start`` to ``goal``: ``width`` [m] of the widest way's
    narrowest opening at ``(x, y)`` [m], ``needed`` [m] (twice the disc radius), ``cell`` [m]."""

    width: float
    x: float
    y: float
    needed: float
    cell: float
    level: float
    best: float

    def reason(self) -> str:
        h = self.cell
        return (f"every way passes an opening at ({self.x:.2f}, {self.y:.2f}) "
                f"{self.width - 0.5 * h:.2f}-{self.width + 0.5 * h:.2f} m wide wall to wall (the "
                f"best of its cells is {self.best:.3f} m from the nearest blocked cell's centre, "
                f"scipy distance_transform_edt of the grid); the last trailer and its clearance "
                f"need {self.needed:.2f} m: its axle midpoint would cross only cells at least "
                f"{self.level:.3f} m from every blocked centre, and those join no way from the "
                "start to the goal")

    def to_toml(self, key: str) -> str:
        return (f'[impossible."{key}"]\nreason = "{self.reason()}"\n'
                f"width = {self.width:.3f}\nat = [{self.x:.2f}, {self.y:.2f}]\n"
                f"needed = {self.needed:.3f}\ncell = {self.cell:g}\n")


def transform(blocked: np.ndarray, h: float) -> np.ndarray:
    """Distance [m] of every cell's centre from the nearest blocked cell's centre (outside the
    grid blocked): scipy's exact Euclidean distance transform."""
    return ndimage.distance_transform_edt(np.pad(~blocked, 1))[1:-1, 1:-1] * h


def _joined(edt: np.ndarray, a, b, level: float) -> bool:
    labels, _ = ndimage.label(edt >= level, structure=_EIGHT)
    return bool(labels[a] > 0 and labels[a] == labels[b])


def maximin(edt: np.ndarray, a, b) -> float | None:
    """The largest ``m`` [m] such that cells at ``m`` or more join cells ``a`` and ``b``
    (8-connected); None if no free cells join them."""
    values = np.unique(edt[edt > 0])
    if not _joined(edt, a, b, values[0]):
        return None
    lo, hi = 0, values.size - 1
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if _joined(edt, a, b, values[mid]):
            lo = mid
        else:
            hi = mid - 1
    return float(values[lo])


def _place(edt: np.ndarray, a, b, m: float) -> tuple[int, int]:
    """The cell at level ``m`` the widest way crosses nearest to both pieces it joins."""
    low, _ = ndimage.label(edt >= m, structure=_EIGHT)
    high, _ = ndimage.label(edt > m, structure=_EIGHT)
    narrow = (low == low[a]) & (edt <= m)
    score = np.zeros(edt.shape)
    for end in (a, b):
        side = high == high[end] if high[end] > 0 else np.zeros(edt.shape, dtype=bool)
        side[end] = True
        score += ndimage.distance_transform_edt(~side)
    score[~narrow] = np.inf
    ti, tj = np.nonzero(score <= score.min() + 1e-9)
    k = int(np.argmin((ti - ti.mean()) ** 2 + (tj - tj.mean()) ** 2))
    return int(ti[k]), int(tj[k])


def prove(grid, start, goal, radius: float) -> Proof | None:
    """The proof (module docstring) that no disc of ``radius`` [m] goes from ``start`` to
    ``goal`` (x, y, ...) [m] on ``grid`` (an OccupancyGrid: ``blocked``, ``x0``, ``y0``,
    ``resolution``), or None where it does not hold (or an end has not that room itself)."""
    h = grid.resolution
    edt = transform(grid.blocked, h)
    a, b = grid.cell_of(*start[:2]), grid.cell_of(*goal[:2])
    level = radius - h / math.sqrt(2.0) + 0.5 * h
    if a is None or b is None or min(edt[a], edt[b]) < level or _joined(edt, a, b, level):
        return None
    m = maximin(edt, a, b)
    if m is None:  # no free way at all: separate parts of the map
        i, j = b
        return Proof(0.0, grid.x0 + h * j, grid.y0 + h * i, 2 * radius, h, level, 0.0)
    i, j = _place(edt, a, b, m)
    return Proof(2.0 * m - 0.5 * h, grid.x0 + h * j, grid.y0 + h * i, 2.0 * radius, h, level, m)


def disc_radius(train, clearance: float) -> float:
    """The last trailer's disc [m]: half its width, or less if its rectangle ends nearer (its
    axle midpoint ``offset`` from its centre), plus ``clearance``."""
    last = train.last
    return min(0.5 * last.width, 0.5 * last.length - abs(last.offset)) + float(clearance)


def prove_mission(mission: dict) -> Proof | None:
    """:func:`prove` for a map mission of bench_facility at the scenario's defaults (its
    train and the last trailer's default clearance)."""
    if "grid" not in mission:
        return None
    from bench_facility import scenario_of

    from pushtrain.mission import runner
    from pushtrain.planner.config import PlannerConfig

    sc = scenario_of(mission, None)
    train = runner.train_of(sc)
    world = runner.world_of(sc)
    clearance = float(PlannerConfig().margins(train)[-1])
    return prove(world.occupancy, mission["start"], mission["goal"],
                 disc_radius(train, clearance))


def main() -> None:
    import bench_facility

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="record the proofs in impossible.toml")
    args = ap.parse_args()
    entries = []
    for m in bench_facility.load_missions():
        if bench_facility.witness_of(m).exists():
            continue
        proof = prove_mission(m)
        print(f"{m['key']}: {'impossible: ' + proof.reason() if proof else 'no proof'}")
        if proof is not None:
            entries.append(proof.to_toml(m["key"]))
    if args.write:
        from pushtrain.files import atomic_write_text

        text = HEADER + "\n" + "\n".join(entries)
        tomllib.loads(text)  # a reason with a quote would break the file: never written so
        atomic_write_text(bench_facility.IMPOSSIBLE, text)
        print(f"{len(entries)} proofs written to {bench_facility.IMPOSSIBLE}", file=sys.stderr)


if __name__ == "__main__":
    sys.path.insert(0, str(HERE))
    main()
