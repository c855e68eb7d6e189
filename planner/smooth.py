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
    disappear this way. Each try costs one closed-loop run of the whole path, so the tries are
    bounded by ``max_tries`` and the deadline.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence

from pushtrain.core.reference import Segment

from .connect import corner_segments, rs_segments, sample_reference
from .lattice_settings import LatticeSettings, segments_cost

__all__ = ["merge", "shortcut", "path_cost", "total_turning", "junction_poses"]


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
    return segments_cost(segments, settings or LatticeSettings(radius=1.0))


def junction_poses(start, segments: Sequence[Segment]) -> list[tuple]:
    """The reference pose at the start of every segment and at the end, (len + 1) poses."""
    poses = [tuple(float(a) for a in start)]
    for g in segments:
        poses.append(tuple(sample_reference(poses[-1], [g], g.length + 1.0)[-1]))
    return poses


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
    simulated. At most ``max_tries`` candidates are simulated, each at least ``min_gain`` (a
    fraction) cheaper than the path so far. Returns (segments, their check, number of
    shortcuts taken).
    """
    best, best_check = list(segments), checked
    taken, tries = 0, 0
    i = 0
    while i < len(best) - 1 and tries < max_tries:
        poses = junction_poses(start, best)
        improved = False
        for j in range(len(best), i + 1, -1):
            if tries >= max_tries or time.perf_counter() >= deadline:
                return best, best_check, taken
            for bridge in _bridges(poses[i], poses[j], best[i].direction, radius):
                candidate = merge(best[:i] + bridge + best[j:])
                if path_cost(candidate) > (1.0 - min_gain) * path_cost(best):
                    continue
                if clear is not None and not clear(poses[i], bridge):
                    continue
                tries += 1
                result = verify(candidate)
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
