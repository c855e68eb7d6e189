"""Local connections between two poses of the last trailer (chain convention), as the line and
arc reference segments the controller tracks: a driver's corner (straight, arc, straight; the
shortest Reeds-Shepp path is :func:`~pushtrain.planner.reeds_shepp.rs_segments`); and poses
sampled along segments. Used by the search
(:mod:`~pushtrain.planner.lattice`) and the smoothing (:mod:`~pushtrain.planner.smooth`)."""

from __future__ import annotations

import math

import numpy as np

from pushtrain.core.field import sample_segments
from pushtrain.core.segment import PUSH, Segment

__all__ = ["corner_segments", "sample_reference", "MAX_CORNER_REACH", "MAX_SAMPLES"]

MAX_CORNER_REACH = 1.0e4
"""Farthest corner [m] of a straight-arc-straight connection: nearly parallel lines of travel
meet arbitrarily far away (1e16 m for opposite headings in floating point); no building has such
a corner."""

MAX_SAMPLES = 2_000_000
"""Most poses :func:`sample_reference` returns (48 MB): 100 km at 5 cm."""


def corner_segments(pose, goal, direction: int, radius: float | None = None,
                    max_radius: float = math.inf,
                    max_reach: float = MAX_CORNER_REACH) -> list[Segment] | None:
    """Straight, arc, straight from ``pose`` to ``goal`` (chain convention) in one
    ``direction`` (PUSH or PULL): the path a driver takes round a corner.

    The two poses' lines of travel must meet ahead of ``pose`` and behind ``goal``; the arc of
    ``radius`` [m] (None: the largest that fits, at most ``max_radius``) is tangent to both.
    Collinear poses give one straight line. Returns None where no such path exists (the lines
    do not meet ahead, the radius does not fit between the corner and the poses, or the travel
    turns by half a turn: parallel lines of opposite directions meet nowhere, and nearly so
    meet farther than ``max_reach`` [m] away: a caller that knows its map passes the map's
    diagonal, since no longer leg fits in it; :data:`MAX_CORNER_REACH` otherwise).
    """
    sigma = -1.0 if direction == PUSH else 1.0
    ax, ay = sigma * math.cos(pose[2]), sigma * math.sin(pose[2])
    bx, by = sigma * math.cos(goal[2]), sigma * math.sin(goal[2])
    dx, dy = goal[0] - pose[0], goal[1] - pose[1]
    cross = ax * by - ay * bx
    alpha = math.atan2(cross, ax * bx + ay * by)  # turn of the direction of travel
    if math.pi - abs(alpha) < 1e-6:
        return None  # a U-turn: no corner of one arc (tan(alpha / 2) is infinite)
    if abs(alpha) < 1e-9:
        lateral = ax * dy - ay * dx
        ahead = float(ax * dx + ay * dy)
        if abs(lateral) > 1e-6 or ahead <= 1e-6:
            return None
        return [Segment("line", ahead, 0.0, direction)]
    # pose + s a = goal - t b
    s = float((dx * by - dy * bx) / cross)
    t = float((dy * ax - dx * ay) / cross)
    if s <= 0.0 or t <= 0.0 or max(s, t) > min(max_reach, MAX_CORNER_REACH):
        return None
    half = math.tan(0.5 * abs(alpha))
    fits = min(s, t) / half
    r = min(fits, max_radius) if radius is None else radius
    if r > fits + 1e-9 or r <= 0.0:
        return None
    tangent = r * half
    out = []
    if s - tangent > 1e-6:
        out.append(Segment("line", s - tangent, 0.0, direction))
    out.append(Segment("arc", r * abs(alpha), math.copysign(1.0 / r, alpha), direction))
    if t - tangent > 1e-6:
        out.append(Segment("line", t - tangent, 0.0, direction))
    return out


def sample_reference(pose, segments, spacing: float) -> np.ndarray:
    """Poses (x, y, theta) along line/arc ``segments`` from ``pose`` every <= ``spacing`` m
    ((count, 3): the pose first, then each segment in max(1, ceil(length / spacing)) equal
    steps), computed in C (:func:`pushtrain.core.field.sample_segments`; its readable twin is
    ``tests/reference/sweep.py``).

    Raises ValueError for a non-finite length or more than :data:`MAX_SAMPLES` poses (a
    caller's bug, never a long path of a real building)."""
    total = sum(max(1, math.ceil(seg.length / spacing)) if math.isfinite(seg.length) else math.inf
                for seg in segments)
    if not total <= MAX_SAMPLES:
        raise ValueError(f"sample_reference: {sum(s.length for s in segments):.6g} m at "
                         f"{spacing} m spacing is more than {MAX_SAMPLES} poses")
    return sample_segments(pose, _segment_table(segments), spacing, total)


def _segment_table(segments) -> np.ndarray:
    """(length [m], curvature [1/m], direction) of each segment, (len, 3) float64: the C
    sweep's input."""
    return np.array([(g.length, g.curvature, g.direction) for g in segments],
                    dtype=float).reshape(-1, 3)
