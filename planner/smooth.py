"""Smoothing of a found path toward the fewest turns: merged pieces and Reeds-Shepp shortcuts.

A search result is a chain of short primitives (and a final Reeds-Shepp connection). Two steps
make it the path a driver would drive:

:func:`merge`
    Consecutive pieces of equal kind, curvature, direction and speed become one segment. The
    reference (and hence the closed loop) is exactly the same; the path just reads as what it
    is ("push 4.5 m straight", not nine half-metre lines).
:func:`shortcut`
    Greedy shortcuts: from each junction of the path (a pose where one piece meets the next),
    the farthest later junction is tried first; the stretch between them is replaced by a
    corner path (straight, one arc, straight) or the Reeds-Shepp path of the planning radius if
    that lowers the path's cost (length, turning, changes of curvature, cusps, as the search
    prices them) and the whole new path passes the closed-loop verification. Hybrid A*'s
    detours (an S-bend of a few centimetres to land on a grid cell)
    disappear this way. Each try costs a closed-loop run of the path from a little before
    where it parts from the path so far (the same run as from the start:
    ``whole_train._simulate``), so the tries are bounded by ``max_tries`` and the deadline.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence

from pushtrain.core.segment import PULL, Segment

from .connect import corner_segments, sample_reference
from .lattice_settings import LatticeSettings, segments_cost
from .reeds_shepp import rs_segments

__all__ = ["merge", "shortcut", "path_cost", "total_turning", "junction_poses"]

_SETTINGS = LatticeSettings(radius=1.0)
"""The prices of :func:`path_cost`."""

_CHEAPEST_METRE = min(1.0, _SETTINGS.pull_factor)
"""The least :func:`path_cost` of a metre of path (pushing 1, pulling ``pull_factor``)."""


def merge(segments: Sequence[Segment]) -> list[Segment]:
    """Consecutive segments of equal kind, curvature, direction and speed joined into one."""
    out: list[Segment] = []
    for g in segments:
        if out and (out[-1].kind, out[-1].curvature, out[-1].direction, out[-1].speed) == (
                g.kind, g.curvature, g.direction, g.speed):
            out[-1] = Segment(g.kind, out[-1].length + g.length, g.curvature, g.direction,
                              g.speed)
        else:
            out.append(g)
    return out


def total_turning(segments: Sequence[Segment]) -> float:
    """The integral of |curvature| over the path [rad]: the heading turned in total."""
    return float(sum(abs(g.curvature) * g.length for g in segments))


def path_cost(segments: Sequence[Segment], settings: LatticeSettings | None = None) -> float:
    """The path's cost as the search prices it (:func:`segments_cost` with ``settings``,
    default :class:`~pushtrain.planner.lattice_settings.LatticeSettings`)."""
    return segments_cost(segments, settings or _SETTINGS)


def junction_poses(start, segments: Sequence[Segment]) -> list[tuple]:
    """The reference pose at the start of every segment and at the end, (len + 1) poses."""
    poses = [tuple(float(a) for a in start)]
    for g in segments:
        poses.append(tuple(sample_reference(poses[-1], [g], g.length + 1.0)[-1]))
    return poses


def _floors(segments: Sequence[Segment]) -> list[float]:
    """Lower bounds of :func:`path_cost` of the first k segments, k = 0..len: their lengths
    and turning at the search's prices, without the changes of curvature and the cusps (all
    prices are >= 0, so the cost of a path that holds these segments is at least this)."""
    s = _SETTINGS
    out = [0.0]
    for g in segments:
        pull = g.direction == PULL
        out.append(out[-1] + g.length * (s.pull_factor if pull else 1.0)
                   + (s.pull_turn_weight if pull else s.turn_weight) * abs(g.curvature) * g.length)
    return out


def _bridges(a, b, direction: int, radius: float):
    """Ways from pose ``a`` to pose ``b``: the corner path (straight, arc, straight) in
    ``direction`` with the widest arc that fits (up to three turning radii) and with the turning
    radius, then the shortest Reeds-Shepp path."""
    for r in (None, radius):
        path = corner_segments(a, b, direction, r, max_radius=3.0 * radius)
        if path:
            yield path
    path = rs_segments(a, b, radius)
    if path:
        yield path


def shortcut(segments: list[Segment], checked, start, goal, radius: float,
             verify: Callable, deadline: float = math.inf, max_tries: int = 8,
             clear: Callable | None = None, min_gain: float = 0.02):
    """Greedy shortcuts (see the module docstring).

    ``verify(segments)`` returns a check result with ``ok``; ``checked`` is the verified check
    of ``segments``. ``clear(pose, bridge)`` (optional) is a cheap necessary test of a bridge
    from ``pose`` (e.g. the last trailer's own footprint along it): a bridge it refuses is not
    simulated. At most ``max_tries`` candidates are tried, each at least ``min_gain`` (a
    fraction) cheaper than the path so far; one tried before (the same segments, from an
    earlier pair of junctions) counts again but is not simulated again. Returns (segments,
    their check, number of shortcuts taken).
    """
    best, best_check = list(segments), checked
    taken, tries = 0, 0
    failed = set()  # the candidates verify refused
    i = 0
    while i < len(best) - 1 and tries < max_tries:
        poses = junction_poses(start, best)
        floors = _floors(best)
        target = (1.0 - min_gain) * path_cost(best)
        improved = False
        for j in range(len(best), i + 1, -1):
            if tries >= max_tries or time.perf_counter() >= deadline:
                return best, best_check, taken
            # no way from junction i to junction j is shorter than the straight line: if
            # even that cannot make the path cheap enough, no bridge is made
            reach = max(0.0, math.dist(poses[i][:2], poses[j][:2]) - 1e-5)
            if floors[i] + (floors[-1] - floors[j]) + _CHEAPEST_METRE * reach > target + 1e-9:
                continue
            for bridge in _bridges(poses[i], poses[j], best[i].direction, radius):
                candidate = merge(best[:i] + bridge + best[j:])
                if path_cost(candidate) > target:
                    continue
                if tuple(candidate) in failed:
                    # tried before from an earlier junction pair (so the bridge was clear):
                    # the simulation is deterministic, it fails again
                    tries += 1
                    continue
                if clear is not None and not clear(poses[i], bridge):
                    continue
                tries += 1
                result = verify(candidate)
                if not result.ok:
                    failed.add(tuple(candidate))
                if result.ok:
                    best, best_check = candidate, result
                    taken += 1
                    improved = True
                    break
            if improved:
                break
        if not improved:
            i += 1
    return best, best_check, taken
