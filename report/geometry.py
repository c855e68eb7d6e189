"""Train geometry for the top views (map and animation): body rectangles, hitch links, the
polyline through the hitches, which rows to draw, and the extent and size of a map.

Conventions as in :mod:`pushtrain.core.kinematics`: positions are the robot centre (body 0) and
the trailers' axle midpoints [m], headings point toward the robot [rad].
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from pushtrain.defaults import ROBOT_LENGTH, ROBOT_WIDTH
from pushtrain.errors import PlotError
from pushtrain.report.data import bodies, check_data, col, pose_columns
from pushtrain.table1 import TRAILER_LENGTH, TRAILER_WIDTH

__all__ = [
    "DEFAULT_FOOTPRINTS",
    "TopView",
    "top_view",
    "footprints_of",
    "body_corners",
    "spaced_snapshots",
    "hitch_links",
    "snapshot_indices",
    "frame_indices",
    "train_polyline",
    "wheel_segments",
    "extent_of",
    "map_size",
    "equal_limits",
]

DEFAULT_FOOTPRINTS = {"robot": (ROBOT_LENGTH, ROBOT_WIDTH),
                      "trailer": (TRAILER_LENGTH, TRAILER_WIDTH)}
"""Body rectangles (length along the heading, width across it) [m], centred on the reference
point of each body (robot centre, trailer axle midpoint); Table 1 of the paper for the trailer."""


# ---------------------------------------------------------------------------------------------
# footprints and body outlines
# ---------------------------------------------------------------------------------------------
def _footprint_entry(value, key: str) -> tuple[float, float, float]:
    if all(hasattr(value, a) for a in ("length", "width")):
        vals = (value.length, value.width, getattr(value, "offset", 0.0))
    else:
        try:
            vals = tuple(float(v) for v in value)
        except (TypeError, ValueError) as exc:
            raise PlotError(f"footprints[{key!r}] = {value!r}: need (length, width) or "
                            "(length, width, offset) in metres") from exc
        if len(vals) == 2:
            vals = (*vals, 0.0)
    if len(vals) != 3:
        raise PlotError(f"footprints[{key!r}] = {value!r}: need (length, width) or "
                        "(length, width, offset) in metres")
    length, width, offset = (float(v) for v in vals)
    if not (math.isfinite(length) and length > 0 and math.isfinite(width) and width > 0
            and math.isfinite(offset)):
        raise PlotError(f"footprints[{key!r}] = {value!r}: length and width must be finite and "
                        "> 0 m, the offset finite")
    return length, width, offset


def footprints_of(footprints: Mapping[str, Any] | None, n: int) -> list[tuple[float, float, float]]:
    """(length, width, offset) [m] of bodies 0..n from the ``footprints`` argument."""
    spec = dict(DEFAULT_FOOTPRINTS)
    if footprints is not None:
        if not isinstance(footprints, Mapping):
            raise PlotError(f"footprints = {footprints!r}: need a dict with keys 'robot', "
                            "'trailer' and/or 'trailers'")
        unknown = sorted(set(footprints) - {"robot", "trailer", "trailers"})
        if unknown:
            raise PlotError(f"footprints has unknown keys {unknown}: allowed are 'robot', "
                            "'trailer' (one size for all) and 'trailers' (one per trailer)")
        spec.update(footprints)
    robot = _footprint_entry(spec["robot"], "robot")
    if "trailers" in spec:
        items = list(spec["trailers"])
        if len(items) != n:
            raise PlotError(f"footprints['trailers'] has {len(items)} entries: need n = {n}")
        trailers = [_footprint_entry(v, f"trailers[{k}]") for k, v in enumerate(items)]
    else:
        trailers = [_footprint_entry(spec["trailer"], "trailer")] * n
    return [robot, *trailers]


def body_corners(x, y, theta, length: float, width: float, offset: float = 0.0) -> np.ndarray:
    """Corners [m] of a body rectangle, shape (..., 4, 2), counter-clockwise.

    Parameters
    ----------
    x, y : float or array
        Reference point (robot centre or axle midpoint) [m].
    theta : float or array
        Heading [rad] (toward the robot).
    length, width : float
        Extent along and across the heading [m].
    offset : float
        Rectangle centre minus reference point along the heading [m].
    """
    x, y, theta = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (x, y, theta)))
    c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]
    along = offset + 0.5 * length * np.array([1.0, -1.0, -1.0, 1.0])
    across = 0.5 * width * np.array([1.0, 1.0, -1.0, -1.0])
    return np.stack([x[..., None] + along * c - across * s,
                     y[..., None] + along * s + across * c], axis=-1)


def hitch_links(data, n: int, geometry=None) -> tuple[np.ndarray, np.ndarray]:
    """Hitch links ``front`` F_1..F_n and ``rear`` R_0..R_{n-1} [m].

    From ``geometry`` (a :class:`~pushtrain.core.kinematics.ChainGeometry`) when given, otherwise
    estimated from the recorded poses: the hitch constraint
    ``P_{i-1} - P_i = R_{i-1} e_{i-1} + F_i e_i`` is solved by least squares over (up to 2000)
    rows. A chain that stays (nearly) straight only fixes F_i + R_{i-1}; the split is then even.
    """
    n = check_data(data, n, pose_columns(n))
    if geometry is not None:
        front = np.asarray(geometry.front, dtype=float).reshape(-1)
        rear = np.asarray(geometry.rear, dtype=float).reshape(-1)
        if front.shape != (n,) or rear.shape != (n,):
            raise PlotError(
                f"geometry has {front.size} front and {rear.size} rear links: need n = {n}"
            )
        return front, rear
    x, y, th = bodies(data, n)
    rows = np.unique(np.linspace(0, len(data) - 1, min(len(data), 2000)).round().astype(int))
    x, y, th = x[rows], y[rows], th[rows]
    front, rear = np.empty(n), np.empty(n)
    for i in range(1, n + 1):
        a = np.concatenate([np.stack([np.cos(th[:, i]), np.cos(th[:, i - 1])], axis=1),
                            np.stack([np.sin(th[:, i]), np.sin(th[:, i - 1])], axis=1)])
        b = np.concatenate([x[:, i - 1] - x[:, i], y[:, i - 1] - y[:, i]])
        ok = np.isfinite(b) & np.all(np.isfinite(a), axis=1)
        (f, r), *_ = np.linalg.lstsq(a[ok], b[ok], rcond=1e-3)
        total = float(np.median(np.hypot(x[:, i - 1] - x[:, i], y[:, i - 1] - y[:, i])))
        front[i - 1] = min(max(f, 0.0), max(total, 0.0))
        rear[i - 1] = min(max(r, 0.0), max(total, 0.0))
    return front, rear


def train_polyline(x, y, th, front) -> tuple[np.ndarray, np.ndarray]:
    """P_0 -> H_1 -> P_1 -> ... -> H_n -> P_n for one instant (hitch H_i = P_i + F_i e_i)."""
    n = len(front)
    hx = x[1:] + front * np.cos(th[1:])
    hy = y[1:] + front * np.sin(th[1:])
    px = np.empty(2 * n + 1)
    py = np.empty(2 * n + 1)
    px[0::2], py[0::2] = x, y
    px[1::2], py[1::2] = hx, hy
    return px, py


def wheel_segments(x, y, th, width, wheel=0.16) -> list:
    """Short segments along the heading at both ends of a trailer axle (the fixed wheels)."""
    c, s = math.cos(th), math.sin(th)
    segs = []
    for side in (1.0, -1.0):
        cx, cy = x - side * 0.5 * width * s, y + side * 0.5 * width * c
        segs.append(((cx - 0.5 * wheel * c, cy - 0.5 * wheel * s),
                     (cx + 0.5 * wheel * c, cy + 0.5 * wheel * s)))
    return segs


# ---------------------------------------------------------------------------------------------
# the recorded run, ready for a top view
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TopView:
    """What a top view draws of a run: times [s], poses of bodies 0..n (rows, n+1) [m, m, rad],
    the last trailer's reference [m, m, rad], hitch links F_i [m], body footprints and the
    planned path (m, 2) [m] or None."""

    n: int
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    th: np.ndarray
    xd: np.ndarray
    yd: np.ndarray
    thd: np.ndarray
    front: np.ndarray
    bodies: list
    path: np.ndarray | None


def _planned_path(path_xy, min_points: int) -> np.ndarray | None:
    if path_xy is None:
        return None
    path = np.asarray(path_xy, dtype=float)
    if path.ndim != 2 or path.shape[1] < 2 or path.shape[0] < min_points:
        raise PlotError(f"path_xy has shape {path.shape}: need (m, 2) points [m]")
    return path[:, :2]


def top_view(data, n: int, *, footprints=None, geometry=None, path_xy=None,
             min_path_points: int = 1) -> TopView:
    """Check the arguments of a top view and gather what it draws (:class:`TopView`)."""
    n = check_data(data, n, pose_columns(n) + ["x_d", "y_d", "theta_d"])
    feet = footprints_of(footprints, n)
    front, _rear = hitch_links(data, n, geometry)
    x, y, th = bodies(data, n)
    return TopView(n=n, t=col(data, "t"), x=x, y=y, th=th, xd=col(data, "x_d"),
                   yd=col(data, "y_d"), thd=col(data, "theta_d"), front=front, bodies=feet,
                   path=_planned_path(path_xy, min_path_points))


# ---------------------------------------------------------------------------------------------
# which rows to draw
# ---------------------------------------------------------------------------------------------
def snapshot_indices(t, count: int) -> np.ndarray:
    """Row indices of ``count`` snapshots evenly spaced in time (nearest sample, no duplicates)."""
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
        raise PlotError(f"snapshots = {count!r}: need an integer >= 0")
    t = np.asarray(t, dtype=float)
    if count == 0 or t.size == 0:
        return np.zeros(0, dtype=int)
    targets = np.linspace(t[0], t[-1], int(count))
    right = np.clip(np.searchsorted(t, targets), 0, t.size - 1)
    left = np.clip(right - 1, 0, t.size - 1)
    pick = np.where(np.abs(t[left] - targets) <= np.abs(t[right] - targets), left, right)
    return np.unique(pick)


def spaced_snapshots(x, y, th, feet, count: int, max_overlap: float = 0.25) -> np.ndarray:
    """Row indices (ascending) of at most ``count`` train snapshots that can be told apart.

    Candidates are ``4 count`` rows evenly spaced in the distance the robot and the last
    trailer have travelled (so a slow final straight gets no more than its share); the last
    row and the first are always taken (a short run's may overlap), then each candidate in
    order whose bodies cover at most ``max_overlap`` of their area with an already taken
    snapshot. ``x``, ``y``, ``th`` are
    (rows, n+1) poses [m, rad]; ``feet`` the (length, width, offset) of each body [m].
    """
    from shapely import Polygon, union_all

    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
        raise PlotError(f"snapshots = {count!r}: need an integer >= 0")
    rows = len(x)
    if count == 0 or rows == 0:
        return np.zeros(0, dtype=int)
    n = x.shape[1] - 1
    step = (np.hypot(np.diff(x[:, 0]), np.diff(y[:, 0]))
            + np.hypot(np.diff(x[:, n]), np.diff(y[:, n])))
    travel = np.concatenate(([0.0], np.cumsum(np.nan_to_num(step))))
    if travel[-1] <= 0.0:
        candidates = np.unique(np.linspace(0, rows - 1, 4 * count).round().astype(int))
    else:
        candidates = np.unique(np.searchsorted(travel, np.linspace(0.0, travel[-1], 4 * count))
                               .clip(0, rows - 1))
    order = [rows - 1, 0] + [int(r) for r in candidates if 0 < r < rows - 1]

    def shape(r):
        return union_all([Polygon(body_corners(x[r, i], y[r, i], th[r, i], *feet[i]))
                          for i in range(n + 1)])

    taken, shapes = [], []
    for r in order:
        if len(taken) >= count or r in taken:
            continue
        g = shape(r)
        if r in (0, rows - 1) or all(g.intersection(h).area <= max_overlap * g.area
                                     for h in shapes):
            taken.append(r)
            shapes.append(g)
    return np.array(sorted(taken), dtype=int)


def frame_indices(rows: int, max_frames: int) -> np.ndarray:
    """Row indices of the animation frames: all rows, or ``max_frames`` evenly spread ones
    (first and last included)."""
    if (isinstance(max_frames, bool) or not isinstance(max_frames, (int, np.integer))
            or max_frames < 1):
        raise PlotError(f"max_frames = {max_frames!r}: need an integer >= 1")
    if rows <= max_frames:
        return np.arange(rows)
    if max_frames == 1:
        return np.array([rows - 1])
    return np.unique(np.linspace(0, rows - 1, int(max_frames)).round().astype(int))


# ---------------------------------------------------------------------------------------------
# map extent and size
# ---------------------------------------------------------------------------------------------
def extent_of(ax_points: list[np.ndarray], world=None) -> tuple[float, float, float, float]:
    """(xmin, xmax, ymin, ymax) [m] of the finite points and the world's bounds, padded by 5 %."""
    pts = np.concatenate([p.reshape(-1, 2) for p in ax_points if p is not None and p.size])
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    xmin, ymin = pts.min(axis=0)
    xmax, ymax = pts.max(axis=0)
    bounds = getattr(world, "bounds", None) if world is not None else None
    if bounds is not None:
        try:
            bx0, by0, bx1, by1 = (float(v) for v in bounds)
            xmin, ymin, xmax, ymax = min(xmin, bx0), min(ymin, by0), max(xmax, bx1), max(ymax, by1)
        except (TypeError, ValueError):
            pass
    pad = 0.05 * max(xmax - xmin, ymax - ymin, 1.0)
    return xmin - pad, xmax + pad, ymin - pad, ymax + pad


def map_size(extent, width: float, extra_w: float, extra_h: float, lo: float = 2.4,
             hi: float = 9.0) -> tuple[tuple[float, float], tuple[float, float, float, float]]:
    """Figure size [in] for a map axes ``width`` inches wide (plus ``extra_w`` x ``extra_h`` for
    legend, colorbar and titles) showing ``extent`` with equal aspect; the axes height is clipped
    to [lo, hi] inches and the extent widened to fill the axes. Returns (size, extent)."""
    xmin, xmax, ymin, ymax = extent
    dx, dy = xmax - xmin, ymax - ymin
    height = float(np.clip(width * dy / max(dx, 1e-9), lo, hi))
    ax_w = width
    if height * dx / max(dy, 1e-9) < width:  # too tall: narrower axes, keep the figure compact
        ax_w = max(height * dx / max(dy, 1e-9), 0.6 * width)
    # widen the shorter side so the data fill an ax_w x height box
    if dy / max(dx, 1e-9) < height / ax_w:
        grow = 0.5 * (dx * height / ax_w - dy)
        ymin, ymax = ymin - grow, ymax + grow
    else:
        grow = 0.5 * (dy * ax_w / height - dx)
        xmin, xmax = xmin - grow, xmax + grow
    return (ax_w + extra_w, height + extra_h), (xmin, xmax, ymin, ymax)


def equal_limits(ax, extent) -> None:
    """Show ``extent`` (xmin, xmax, ymin, ymax) [m] on ``ax`` with equal axis scales."""
    xmin, xmax, ymin, ymax = extent
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal", adjustable="box")
