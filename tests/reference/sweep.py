"""The last trailer swept along line and arc segments, written out in Python one pose at a time:
the references ``core/csrc/field.c``'s ``pt_sample_segments`` (behind
:func:`pushtrain.planner.connect.sample_reference`) and ``pt_poses_clear`` (behind
:meth:`pushtrain.planner.lattice.Search.reference_clear`) are held equal to, bit for bit.
SI units, radians."""

from __future__ import annotations

import math

from .field_lookup import field_at


def sample_poses(pose, segments, spacing: float) -> list[tuple[float, float, float]]:
    """Poses (x, y, theta) from ``pose`` along ``segments`` (each with ``length`` [m],
    ``curvature`` [1/m] and ``direction``: +1 push, -1 pull), each segment in
    max(1, ceil(length / spacing)) equal steps; the pose itself first. A push moves the
    last trailer along theta + pi (chain convention): sigma = -direction."""
    x, y, th = (float(a) for a in pose)
    out = [(x, y, th)]
    for seg in segments:
        sigma = -float(seg.direction)
        m = max(1, int(math.ceil(seg.length / spacing)))
        ds = seg.length / m
        k = seg.curvature
        if abs(k) < 1e-12:
            dx = sigma * ds * math.cos(th)
            dy = sigma * ds * math.sin(th)
            for _ in range(m):
                x += dx
                y += dy
                out.append((x, y, th))
        else:
            s0, c0 = math.sin(th), math.cos(th)
            for _ in range(m):
                th += k * ds
                s1, c1 = math.sin(th), math.cos(th)
                x += sigma * (s1 - s0) / k
                y += -(sigma * (c1 - c0) / k)
                s0, c0 = s1, c1
                out.append((x, y, th))
    return out


def poses_clear(values, x0: float, y0: float, h: float, poses, reach: float, points) -> bool:
    """Whether every point (u, v, threshold) of ``points`` (in the body's frame, u along
    theta [m]) keeps its threshold [m] of signed distance at every pose; a pose whose own
    distance is not below ``reach`` [m] passes without its points."""
    for x, y, th in poses:
        if not field_at(values, x0, y0, h, x, y) < reach:
            continue
        c, s = math.cos(th), math.sin(th)
        for u, v, threshold in points:
            if not field_at(values, x0, y0, h, x + u * c - v * s, y + u * s + v * c) >= threshold:
                return False
    return True
