"""Proofs that a facility mission is impossible, independent of the planner (issue 34 items 3-4).

Usage: python benchmarks/prove_impossible.py [--write]

For every mission of ``benchmarks/facility/missions.toml`` without a witness it tries the proof
below on the scenario's World (``pushtrain.mission.runner.world_of``: for a map_server grid, the
free space traced by ``facility/raster.py``, the geometry the planner and the co-simulation
check bodies against), with shapely alone (no distance field, route or search of the planner),
and prints it; ``--write`` records the missions it proves in ``benchmarks/facility/
impossible.toml`` (atomically, the file's header kept).

The proof (no way of the last trailer's width)
    Wherever the last trailer goes, the disc of radius ``r`` round its axle midpoint (half its
    width, or less if its rectangle ends nearer, plus its clearance: what the planner's
    ``needed_half_width`` asks, from the Train's geometry and the default clearance) lies in
    the free space ``F``, so the midpoint stays in ``F`` eroded by ``r``
    (``F.buffer(-r)``, shapely/GEOS). A continuous way stays in one connected part of it: if
    the part holding the start does not hold the goal, the train has no way on this map.
    GEOS draws the eroded set's round corners with chords whose vertices lie on the arcs
    (``quad_segs = 32``: at most ``r (1 - cos(pi / 128))``, 0.1 mm, inside the exact set's
    boundary), so the polygon holds the exact eroded set: parts separate in it are separate
    in the exact one, and the proof never overstates. It erodes by ``r`` less half a
    millimetre: a way exactly ``2 r`` wide erodes to a line, which GEOS drops.
The width named
    The widest way's: the largest disc diameter ``2 rho`` whose eroded free space still joins
    start and goal, by bisection on ``rho`` until the bracket is below half a millimetre
    (width to 1 mm; eroding the last joined part further, as erosions by discs compose).
    It is where the start's and the goal's parts come closest at the bracket's upper end
    (the middle of shapely's ``shortest_line`` between them). This is the geometry's own
    width (a door of width ``D`` between square jambs gives ``D``), which the planner's
    "impossible here" must name within ``bench_facility.WIDTH_TOLERANCE`` (5 cm).
No grid transform is kept as a cross-check. The first proof here (scipy's EDT over the
cells' centres, a blocked cell taken as a disc of ``h / 2``) is not the traced geometry, whose
corners are cut to about ``0.35 h`` of a blocked centre; with that cell model, the cells a way
crosses keep only ``r - h / sqrt 2 + 0.35 h`` (0.314 m at 10 cm cells) from blocked centres,
which joins start and goal for 4 of the 6 office missions (sw_office and w_office, measured):
it would check only 2, and name widths only within a cell. The tests check each recorded proof
by their own erosion instead.

Lengths in metres.
"""

from __future__ import annotations

import argparse
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

from shapely import shortest_line
from shapely.geometry import Point

HERE = Path(__file__).resolve().parent
QUAD_SEGS = 32
"""Chords per quarter circle of the eroded set's round corners (at most 0.1 mm short of the
arc at 0.35 m)."""
PRECISION = 0.0005
"""Bisection bracket on the radius [m] (the width to 1 mm)."""
REBASE = 0.01
"""Below this bracket [m] the bisection erodes one fixed part (each erosion of an eroded set
draws its round corners again, and the vertices, so the time, grow with every step)."""
HEADER = """\
# Missions of the facility benchmark shown impossible, each with its proof: computed by
# benchmarks/prove_impossible.py on the scenario's World (the free space traced from the map's
# grid, which the planner and the co-simulation check against) with shapely, independently of
# the planner (issue 34 items 3-4; the proof is in that script's docstring). `width` [m] is
# the widest disc that joins start and goal (to 1 mm, bisection of the erosion's radius), its
# narrowest place at `at` [x, y m]; `needed` [m] the disc the last trailer and its clearance
# need. Written by `python benchmarks/prove_impossible.py --write`.
"""


@dataclass(frozen=True)
class Proof:
    """No way of the last trailer from the start to the goal: ``width`` [m], the widest disc
    that joins them (0 if no way at all), narrowest at ``(x, y)`` [m]; ``needed`` [m], the
    disc the last trailer and its clearance need."""

    width: float
    x: float
    y: float
    needed: float

    def reason(self) -> str:
        if self.width == 0.0:
            return ("start and goal lie in separate parts of the map's free space (shapely): no "
                    "way at all")
        return (f"the widest way narrows at ({self.x:.2f}, {self.y:.2f}) to {self.width:.3f} m "
                f"(the largest disc that joins start and goal through the map's free space, "
                f"shapely erosion bisected to 1 mm); the last trailer and its clearance need "
                f"{self.needed:.3f} m: the free space eroded by "
                f"{0.5 * self.needed - PRECISION:.4f} m leaves the start and the goal in "
                "separate parts")

    def to_toml(self, key: str) -> str:
        return (f'[impossible."{key}"]\nreason = "{self.reason()}"\n'
                f"width = {self.width:.3f}\nat = [{self.x:.2f}, {self.y:.2f}]\n"
                f"needed = {self.needed:.3f}\n")


def _parts(geom):
    return getattr(geom, "geoms", (geom,))


def part_holding(geom, point: Point):
    """The connected part (a Polygon) of ``geom`` that holds ``point``, or None."""
    for part in _parts(geom):
        if not part.is_empty and part.covers(point):
            return part
    return None


def eroded(geom, radius: float):
    """``geom`` eroded by a disc of ``radius`` [m] (a superset of the exact set by at most
    0.1 mm, see the module docstring)."""
    return geom.buffer(-radius, quad_segs=QUAD_SEGS)


def prove(free, start, goal, radius: float) -> Proof | None:
    """The proof (module docstring) that no disc of ``radius`` [m] goes from ``start`` to
    ``goal`` (x, y, ...) [m] through ``free`` (a shapely (Multi)Polygon: a World's ``free``),
    or None where it does not hold (or an end has not that room itself)."""
    s, g = Point(start[:2]), Point(goal[:2])
    piece = part_holding(free, s)
    if piece is None or not free.covers(g):
        return None  # an end inside an obstacle: not a question of the way
    if not piece.covers(g):  # no way at all: separate parts of the map
        return Proof(0.0, float(g.x), float(g.y), 2.0 * radius)
    at_need = eroded(piece, radius - PRECISION)  # a way exactly the disc's width passes:
    # eroded by the full radius it is a line, which GEOS drops
    start_part = part_holding(at_need, s)
    if start_part is None or not at_need.covers(g) or start_part.covers(g):
        return None
    lo, hi = 0.0, radius
    base, base_lo = piece, 0.0  # the part holding both at radius base_lo <= lo
    while hi - lo > PRECISION:
        mid = 0.5 * (lo + hi)
        part = part_holding(eroded(base, mid - base_lo), s)  # erosions by discs compose
        if part is not None and part.covers(g):
            lo = mid
            if hi - lo > REBASE:  # eroding an eroded part again adds vertices: only while coarse
                base, base_lo = part, mid
        else:
            hi = mid
    split = eroded(base, hi - base_lo)
    a, b = part_holding(split, s), part_holding(split, g)
    if a is None or b is None:  # an end lost its room above lo: name the end
        x, y = (s.x, s.y) if a is None else (g.x, g.y)
    else:
        x, y = shortest_line(a, b).interpolate(0.5, normalized=True).coords[0]
    return Proof(round(2.0 * lo, 3), float(x), float(y), 2.0 * radius)


def disc_radius(train, clearance: float) -> float:
    """The last trailer's disc [m]: half its width, or less if its rectangle ends nearer (its
    axle midpoint ``offset`` from its centre), plus ``clearance`` (the planner's
    ``needed_half_width``, written here again so that the proof uses no planner code)."""
    last = train.last
    return min(0.5 * last.width, 0.5 * last.length - abs(last.offset)) + float(clearance)


def mission_world_and_radius(mission: dict):
    """The scenario's World and the last trailer's disc radius [m] at the scenario's defaults
    (its train and the last trailer's default clearance), or None for a mission without a
    map grid."""
    if "grid" not in mission:
        return None
    from bench_facility import scenario_of

    from pushtrain.mission import runner
    from pushtrain.planner.config import PlannerConfig

    sc = scenario_of(mission, None)
    train = runner.train_of(sc)
    clearance = float(PlannerConfig().margins(train)[-1])
    return runner.world_of(sc), disc_radius(train, clearance)


def prove_mission(mission: dict) -> Proof | None:
    """:func:`prove` for a map mission of bench_facility at the scenario's defaults."""
    found = mission_world_and_radius(mission)
    if found is None:
        return None
    world, radius = found
    return prove(world.free, mission["start"], mission["goal"], radius)


def main() -> None:
    import bench_facility

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="record the proofs in impossible.toml")
    args = ap.parse_args()
    entries, done = [], {}
    for m in bench_facility.load_missions():
        if bench_facility.witness_of(m).exists():
            continue
        found = mission_world_and_radius(m)
        proof = None
        if found is not None:
            world, radius = found
            key = (m["grid"], tuple(m["start"][:2]), tuple(m["goal"][:2]), radius)
            if key not in done:  # n = 1 and n = 3 share the last trailer
                done[key] = prove(world.free, m["start"], m["goal"], radius)
            proof = done[key]
        print(f"{m['key']}: {'impossible: ' + proof.reason() if proof else 'no proof'}",
              flush=True)
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
