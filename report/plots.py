"""Figures and an animation of a co-simulation run (matplotlib with the Agg canvas, no pyplot).

Every function takes the structured array ``data`` of :attr:`pushtrain.cosim.master.Result.data`
(columns as in ``master._columns(n)``) and the number of trailers ``n``. The ``plot_*`` functions
and :func:`animate` write one file each, atomically (a temporary file in the same folder, then
``os.replace``), and return its path; :func:`plot_all` writes the standard set into a folder.
The ``*_figure`` functions build the same figures without saving them (for tests and notebooks).

Conventions as in :mod:`pushtrain.core.kinematics`: positions are the robot centre (body 0) and
the trailers' axle midpoints [m], headings point toward the robot [rad]. Plots show angles in
degrees, lateral and longitudinal errors in centimetres.

Nothing here imports pyplot, so figures never reach a GUI and the global pyplot state is untouched.
"""

from __future__ import annotations

import logging
import math
import time as _time
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from matplotlib import colormaps
from matplotlib.animation import PillowWriter
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import (BoundaryNorm, LinearSegmentedColormap, ListedColormap, Normalize,
                               to_rgb)
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.patches import Polygon as PolygonPatch
from PIL import Image

from pushtrain.errors import PlotError
from pushtrain.files import atomic_write

__all__ = [
    "PlotError",
    "DPI",
    "DEFAULT_FOOTPRINTS",
    "plot_map",
    "plot_inputs_and_joints",
    "plot_tracking_error",
    "plot_lateral_forces",
    "animate",
    "plot_all",
    "map_figure",
    "inputs_and_joints_figure",
    "tracking_error_figure",
    "lateral_forces_figure",
    "snapshot_indices",
    "frame_indices",
    "hitch_links",
    "body_corners",
]

log = logging.getLogger(__name__)

DPI = 120
"""Resolution of the PNG figures [dots per inch]."""

GIF_DPI = 80
"""Resolution of the animation frames [dots per inch] (kept low so 150 frames render in seconds)."""

DEFAULT_FOOTPRINTS = {"robot": (0.6, 0.5), "trailer": (0.8, 0.6)}
"""Body rectangles (length along the heading, width across it) [m], centred on the reference
point of each body (robot centre, trailer axle midpoint); Table 1 of the paper for the trailer."""

# colours shared by the figures
_C_ROBOT = "tab:red"
_C_LAST = "tab:blue"
_C_REF = "black"
_C_PATH = "0.55"
_C_SLIP = "tab:orange"
_C_JACK = "magenta"
_C_DIST = "tab:red"
_DIRECTION_BANDS = ((1, "#d5e5f6", "push (trailer first)"), (-1, "#fbe0c3", "pull (robot first)"),
                    (0, "#e6e6e6", "rest"))
# snapshots fade from light (early) to dark (late)
_SNAPSHOT_CMAP = LinearSegmentedColormap.from_list("snapshot_fade", ["#b9c8d8", "#17324d"])


# ---------------------------------------------------------------------------------------------
# validation and data access
# ---------------------------------------------------------------------------------------------
def _check_n(n) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise PlotError(f"n = {n!r}: the number of trailers must be an integer >= 1")
    return int(n)


def _check_data(data, n, columns: Sequence[str]) -> int:
    """Check that ``data`` is a non-empty structured array with ``columns`` for ``n`` trailers."""
    n = _check_n(n)
    names = getattr(getattr(data, "dtype", None), "names", None)
    if names is None:
        raise PlotError(
            f"data is a {type(data).__name__}: need the structured array of Result.data "
            "(one named column per recorded variable)"
        )
    missing = [c for c in columns if c not in names]
    if missing:
        raise PlotError(
            f"data lacks the column(s) {missing[:6]}{' ...' if len(missing) > 6 else ''} needed "
            f"for n = {n} trailers; it has {len(names)} columns ({', '.join(names[:6])}, ...)"
        )
    if f"x{n + 1}" in names:
        raise PlotError(
            f"n = {n} but data has a column x{n + 1}: it records more than {n} trailers"
        )
    if len(data) == 0:
        raise PlotError("data has no rows: nothing to plot")
    return n


def _col(data, name: str) -> np.ndarray:
    return np.asarray(data[name], dtype=float)


def _bodies(data, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions and headings of bodies 0..n, each of shape (rows, n+1) [m, m, rad]."""
    x = np.stack([_col(data, f"x{i}") for i in range(n + 1)], axis=1)
    y = np.stack([_col(data, f"y{i}") for i in range(n + 1)], axis=1)
    th = np.stack([_col(data, f"theta{i}") for i in range(n + 1)], axis=1)
    return x, y, th


def _pose_columns(n: int) -> list[str]:
    return ["t"] + [f"{b}{i}" for b in ("x", "y", "theta") for i in range(n + 1)]


def _output_path(out_path, allowed: Sequence[str] | None = None) -> Path:
    """``out_path`` as a Path whose suffix names a format this module can write."""
    path = Path(out_path)
    fmt = path.suffix.lower().lstrip(".")
    if allowed is None:
        allowed = sorted(FigureCanvasAgg(Figure()).get_supported_filetypes())
    if fmt not in allowed:
        raise PlotError(f"out_path = {str(out_path)!r}: the suffix must be one of "
                        f"{', '.join('.' + a for a in allowed)}")
    return path


def _atomic(path: Path, write) -> Path:
    """Call ``write(partial)`` on a temporary name in ``path``'s folder, then rename it to ``path``.

    The temporary name keeps the suffix (matplotlib and Pillow choose the format by it); it is
    removed whatever happens, so a failure leaves neither a partial file nor a changed ``path``.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write(path, write, keep_suffix=True)


def _save(fig: Figure, out_path, dpi: float = DPI) -> Path:
    path = _output_path(out_path)
    fmt = path.suffix.lower().lstrip(".")
    _atomic(path, lambda partial: fig.savefig(partial, format=fmt, dpi=dpi))
    return path


def _new_figure(width: float, height: float, dpi: float = DPI) -> Figure:
    fig = Figure(figsize=(width, height), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _series_colors(count: int, categorical: bool = True) -> list:
    """Colours of ``count`` series: tab10 when ``categorical`` and count <= 10, else viridis."""
    if categorical and count <= 10:
        return [colormaps["tab10"](k) for k in range(count)]
    return [colormaps["viridis"](v) for v in np.linspace(0.0, 0.9, count)]


def _index_colorbar(fig, ax, colors: list, label: str) -> None:
    """A discrete colour bar mapping colours[k] to index k + 1."""
    count = len(colors)
    norm = BoundaryNorm(np.arange(0.5, count + 1.0), count)
    bar = fig.colorbar(ScalarMappable(norm=norm, cmap=ListedColormap(colors)), ax=ax, pad=0.01)
    bar.set_ticks(np.unique(np.linspace(1, count, min(count, 10)).round()))
    bar.set_label(label)


def _intervals(t: np.ndarray, mask: np.ndarray) -> list[tuple[float, float]]:
    """Time intervals [s] where ``mask`` holds; each lasts until the next sample after it ends."""
    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        return []
    edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    starts = np.flatnonzero(edges == 1)
    stops = np.flatnonzero(edges == -1)  # first index after each run
    last = len(t) - 1
    return [(float(t[a]), float(t[min(b, last)])) for a, b in zip(starts, stops)]


def _disturbance_mask(data) -> np.ndarray:
    names = data.dtype.names
    mask = np.zeros(len(data), dtype=bool)
    for name in ("push_x", "push_y", "slide"):
        if name in names:
            mask |= np.abs(_col(data, name)) > 0.0
    return mask


def _shade(ax, spans, color, alpha, label=None, **kwargs) -> None:
    for k, (a, b) in enumerate(spans):
        ax.axvspan(a, b, color=color, alpha=alpha, lw=0, label=label if k == 0 else None, **kwargs)


# ---------------------------------------------------------------------------------------------
# geometry helpers
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


def _footprints(footprints: Mapping[str, Any] | None, n: int) -> list[tuple[float, float, float]]:
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
    n = _check_data(data, n, _pose_columns(n))
    if geometry is not None:
        front = np.asarray(geometry.front, dtype=float).reshape(-1)
        rear = np.asarray(geometry.rear, dtype=float).reshape(-1)
        if front.shape != (n,) or rear.shape != (n,):
            raise PlotError(
                f"geometry has {front.size} front and {rear.size} rear links: need n = {n}"
            )
        return front, rear
    x, y, th = _bodies(data, n)
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


def _train_polyline(x, y, th, front) -> tuple[np.ndarray, np.ndarray]:
    """P_0 -> H_1 -> P_1 -> ... -> H_n -> P_n for one instant (hitch H_i = P_i + F_i e_i)."""
    n = len(front)
    hx = x[1:] + front * np.cos(th[1:])
    hy = y[1:] + front * np.sin(th[1:])
    px = np.empty(2 * n + 1)
    py = np.empty(2 * n + 1)
    px[0::2], py[0::2] = x, y
    px[1::2], py[1::2] = hx, hy
    return px, py


def _wheel_segments(x, y, th, width, wheel=0.16) -> list:
    """Short segments along the heading at both ends of a trailer axle (the fixed wheels)."""
    c, s = math.cos(th), math.sin(th)
    segs = []
    for side in (1.0, -1.0):
        cx, cy = x - side * 0.5 * width * s, y + side * 0.5 * width * c
        segs.append(((cx - 0.5 * wheel * c, cy - 0.5 * wheel * s),
                     (cx + 0.5 * wheel * c, cy + 0.5 * wheel * s)))
    return segs


def _extent(ax_points: list[np.ndarray], world=None) -> tuple[float, float, float, float]:
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


def _map_size(extent, width: float, extra_w: float, extra_h: float, lo: float = 2.4,
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


def _equal_limits(ax, extent) -> None:
    xmin, xmax, ymin, ymax = extent
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal", adjustable="box")


# ---------------------------------------------------------------------------------------------
# 1. map
# ---------------------------------------------------------------------------------------------
def map_figure(data, n: int, *, world=None, path_xy=None, footprints=None, snapshots: int = 8,
               title: str | None = None, geometry=None) -> Figure:
    """The top view of :func:`plot_map` as an unsaved Figure.

    Snapshot artists carry gids ``"snapshot{k}:body{i}"`` (rectangles), ``"snapshot{k}:train"``
    (the line P_0 -> H_1 -> P_1 -> ... -> P_n through the hitch points) for snapshot k at row
    ``snapshot_indices(data['t'], snapshots)[k]``.
    """
    n = _check_data(data, n, _pose_columns(n) + ["x_d", "y_d", "theta_d"])
    bodies = _footprints(footprints, n)
    idx = snapshot_indices(_col(data, "t"), snapshots)
    front, _rear = hitch_links(data, n, geometry)
    t = _col(data, "t")
    x, y, th = _bodies(data, n)
    xd, yd, thd = _col(data, "x_d"), _col(data, "y_d"), _col(data, "theta_d")
    path = None
    if path_xy is not None:
        path = np.asarray(path_xy, dtype=float)
        if path.ndim != 2 or path.shape[1] < 2 or path.shape[0] < 1:
            raise PlotError(f"path_xy has shape {path.shape}: need (m, 2) points [m]")
        path = path[:, :2]

    corners = {(k, i): body_corners(x[r, i], y[r, i], th[r, i], *bodies[i])
               for k, r in enumerate(idx) for i in range(n + 1)}
    goal_box = body_corners(xd[-1], yd[-1], thd[-1], *bodies[n])
    extent = _extent([np.stack([x.ravel(), y.ravel()], axis=1), np.stack([xd, yd], axis=1), path,
                      goal_box, *corners.values()], world)
    size, extent = _map_size(extent, 6.8, 2.6, 1.5)
    fig = _new_figure(*size)
    ax = fig.add_subplot()
    if world is not None:
        world.plot(ax)

    if path is not None:
        ax.plot(path[:, 0], path[:, 1], "-", color=_C_PATH, lw=2.5, alpha=0.6, zorder=2,
                label="planned path (last trailer)")
    ax.plot(xd, yd, "--", color=_C_REF, lw=1.3, zorder=22, label="reference (last trailer)")
    ax.plot(x[:, n], y[:, n], "-", color=_C_LAST, lw=1.8, zorder=21,
            label=f"last trailer ({n}) trace")
    ax.plot(x[:, 0], y[:, 0], "-", color=_C_ROBOT, lw=1.8, zorder=21, label="robot trace")

    norm = Normalize(vmin=t[0], vmax=t[-1] if t[-1] > t[0] else t[0] + 1.0)
    for k, r in enumerate(idx):
        color = _SNAPSHOT_CMAP(norm(t[r]))
        z = 5 + k / max(len(idx), 1)
        for i in range(n + 1):
            patch = PolygonPatch(corners[(k, i)], closed=True, facecolor=color,
                                 alpha=0.55 if i == 0 else 0.14, edgecolor="none", zorder=z)
            patch.set_gid(f"snapshot{k}:body{i}")
            ax.add_patch(patch)
            ax.add_patch(PolygonPatch(corners[(k, i)], closed=True, fill=False, edgecolor=color,
                                      lw=1.3 if i == 0 else 0.8, zorder=z))
            if i > 0:
                for seg in _wheel_segments(x[r, i], y[r, i], th[r, i], bodies[i][1]):
                    ax.plot(*zip(*seg), "-", color=color, lw=2.6, solid_capstyle="butt", zorder=z)
        px, py = _train_polyline(x[r], y[r], th[r], front)
        (line,) = ax.plot(px, py, "-", color=color, lw=1.2, zorder=z + 0.01)
        line.set_gid(f"snapshot{k}:train")
        ax.plot(px[1::2], py[1::2], "o", ms=2.5, color=color, zorder=z + 0.01)  # hitch points
        # robot heading: a tick from its centre to its front edge
        head = 0.5 * bodies[0][0] + bodies[0][2]
        ax.plot([x[r, 0], x[r, 0] + head * math.cos(th[r, 0])],
                [y[r, 0], y[r, 0] + head * math.sin(th[r, 0])], "-", color="white", lw=1.4,
                zorder=z + 0.02)

    ax.add_patch(PolygonPatch(goal_box, closed=True, fill=False, edgecolor="tab:green", lw=1.4,
                              ls="--", zorder=23, label="goal pose (last trailer)"))
    ax.plot([x[0, n]], [y[0, n]], "o", color="tab:green", mec="black", ms=9, zorder=24,
            label="start (last trailer)")
    ax.plot([xd[-1]], [yd[-1]], "*", color="tab:green", mec="black", ms=14, zorder=24,
            label="goal (reference end)")

    names = data.dtype.names
    slip_x, slip_y = [], []
    for i in range(1, n + 1):
        if f"slipping{i}" in names:
            m = _col(data, f"slipping{i}") > 0.5
            slip_x.append(x[m, i])
            slip_y.append(y[m, i])
    if slip_x and sum(a.size for a in slip_x):
        ax.plot(np.concatenate(slip_x), np.concatenate(slip_y), "x", color=_C_SLIP, ms=4,
                mew=1.0, zorder=25, label="wheel slipping")
    if "jackknifed" in names and np.any(_col(data, "jackknifed") > 0.5):
        j = int(np.flatnonzero(_col(data, "jackknifed") > 0.5)[0])
        ax.plot([x[j, n]], [y[j, n]], "X", color=_C_JACK, mec="black", ms=12, zorder=26,
                label=f"jackknife (t = {t[j]:.1f} s)")

    _equal_limits(ax, extent)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, lw=0.4, alpha=0.5)
    handles, labels = ax.get_legend_handles_labels()
    if len(idx):
        shade = _SNAPSHOT_CMAP(0.6)
        handles.append(Patch(facecolor=shade, edgecolor=shade, alpha=0.5))
        labels.append(f"train, {len(idx)} snapshots")
    ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8,
              frameon=False)
    if len(idx):
        bar = fig.colorbar(ScalarMappable(norm=norm, cmap=_SNAPSHOT_CMAP), ax=ax, location="bottom",
                           shrink=0.6, aspect=35, pad=0.02)
        bar.set_label("snapshot time t [s]")
    ax.set_title(title or f"Backward motion of a robot with {n} trailer{'s' if n > 1 else ''}: "
                 f"top view ({t[-1] - t[0]:.1f} s)")
    return fig


def plot_map(data, n: int, out_path, *, world=None, path_xy=None, footprints=None,
             snapshots: int = 8, title: str | None = None, geometry=None) -> Path:
    """Top view of a run (the paper's Fig. 9/11/13): reference, traces and train snapshots.

    Parameters
    ----------
    data : numpy structured array
        ``Result.data`` of a run with ``n`` trailers.
    n : int
        Number of trailers.
    out_path : path-like
        Image file (``.png``, ``.svg``, ``.pdf``, ...); written atomically.
    world : object with ``plot(ax)``, optional
        Walls and free space (:class:`pushtrain.planner.world.World`).
    path_xy : array of shape (m, 2), optional
        The planned dense path of the last trailer [m].
    footprints : dict, optional
        ``'robot'`` and ``'trailer'`` (one size for all) or ``'trailers'`` (n entries), each
        ``(length, width)`` or ``(length, width, offset)`` [m] or an object with those attributes;
        default :data:`DEFAULT_FOOTPRINTS`.
    snapshots : int
        Number of train snapshots evenly spread in time (0: none).
    title : str, optional
        Figure title.
    geometry : ChainGeometry, optional
        Hitch links for drawing the hitch points; default: estimated from the poses.

    Returns
    -------
    pathlib.Path
        ``out_path``.
    """
    path = _output_path(out_path)
    return _save(map_figure(data, n, world=world, path_xy=path_xy, footprints=footprints,
                            snapshots=snapshots, title=title, geometry=geometry), path)


# ---------------------------------------------------------------------------------------------
# 2. inputs and joint angles
# ---------------------------------------------------------------------------------------------
def inputs_and_joints_figure(data, n: int) -> Figure:
    """The figure of :func:`plot_inputs_and_joints`, unsaved.

    Line gids: ``v_cmd``, ``v0``, ``w_cmd``, ``w0``, ``phi{i}`` and ``phi_meas{i}`` (only where the
    measurement differs from the true angle).
    """
    cols = ["t", "v0", "w0", "v_cmd", "w_cmd"] + [f"phi{i}" for i in range(1, n + 1)]
    n = _check_data(data, n, cols)
    t = _col(data, "t")
    fig = _new_figure(8.0, 8.0)
    axes = fig.subplots(3, 1, sharex=True, height_ratios=(1.0, 1.0, 1.4))
    disturbance = _intervals(t, _disturbance_mask(data))
    for k, ax in enumerate(axes):
        _shade(ax, disturbance, _C_DIST, 0.12, label="disturbance (push/slide)" if k == 0 else None)
        ax.axhline(0.0, color="0.3", lw=0.6)
        ax.grid(True, lw=0.4, alpha=0.5)

    ax = axes[0]
    ax.plot(t, _col(data, "v_cmd"), "--", color="tab:gray", lw=1.3, label="command v_cmd",
            gid="v_cmd")
    ax.plot(t, _col(data, "v0"), "-", color=_C_ROBOT, lw=1.4, label="actual v0", gid="v0")
    ax.set_ylabel("v0 [m/s]")
    ax.set_title("Robot longitudinal speed (negative: pushing)", fontsize=10)
    ax.legend(loc="best", fontsize=8)

    ax = axes[1]
    ax.plot(t, np.degrees(_col(data, "w_cmd")), "--", color="tab:gray", lw=1.3,
            label="command w_cmd", gid="w_cmd")
    ax.plot(t, np.degrees(_col(data, "w0")), "-", color=_C_ROBOT, lw=1.4, label="actual w0",
            gid="w0")
    ax.set_ylabel("w0 [deg/s]")
    ax.set_title("Robot yaw rate", fontsize=10)
    ax.legend(loc="best", fontsize=8)

    ax = axes[2]
    colors = _series_colors(n, categorical=n <= 12)
    names = data.dtype.names
    any_meas = False
    for i in range(1, n + 1):
        phi = np.degrees(_col(data, f"phi{i}"))
        ax.plot(t, phi, "-", color=colors[i - 1], lw=1.4, label=f"phi{i}", gid=f"phi{i}")
        if f"phi_meas{i}" in names:
            meas = np.degrees(_col(data, f"phi_meas{i}"))
            if np.nanmax(np.abs(meas - phi)) > 1e-6:
                any_meas = True
                ax.plot(t, meas, ":", color=colors[i - 1], lw=1.4, gid=f"phi_meas{i}")
    ax.set_ylabel("joint angle phi_i [deg]")
    ax.set_xlabel("time t [s]")
    ax.set_title("Joint angles phi_i = theta_(i-1) - theta_i" +
                 (" (solid: true, dotted: measured)" if any_meas else ""), fontsize=10)
    handles, labels = ax.get_legend_handles_labels()
    if any_meas:
        handles += [Line2D([], [], color="0.3", ls="-"), Line2D([], [], color="0.3", ls=":")]
        labels += ["true", "measured"]
    if n <= 12:
        ax.legend(handles, labels, loc="best", fontsize=8, ncol=max(1, min(4, (n + 3) // 4)))
    else:
        _index_colorbar(fig, ax, colors, "joint index i")
    axes[0].set_xlim(t[0], t[-1] if t[-1] > t[0] else t[0] + 1.0)
    fig.suptitle(f"Robot inputs and joint angles ({n} trailer{'s' if n > 1 else ''})")
    return fig


def plot_inputs_and_joints(data, n: int, out_path) -> Path:
    """Robot speed and yaw rate (command and actual) and the joint angles over time (Fig. 10/12).

    Speeds in m/s, yaw rates in deg/s, joint angles in degrees (true solid, measured dotted when
    the sensors differ); disturbance intervals (push force, imposed slide) are shaded.
    Returns the written path.
    """
    path = _output_path(out_path)
    return _save(inputs_and_joints_figure(data, n), path)


# ---------------------------------------------------------------------------------------------
# 3. tracking error
# ---------------------------------------------------------------------------------------------
def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a**2)))


def tracking_error_figure(data, n: int) -> Figure:
    """The figure of :func:`plot_tracking_error`, unsaved (line gids ``e_lat``, ``e_lon``,
    ``e_theta``; the direction bands are spans with gids ``direction+1`` (push), ``direction-1``
    (pull) and ``direction+0`` (rest))."""
    n = _check_data(data, n, ["t", "e_lat", "e_lon", "e_theta", "direction"])
    t = _col(data, "t")
    direction = np.rint(_col(data, "direction"))
    fig = _new_figure(8.0, 7.0)
    axes = fig.subplots(3, 1, sharex=True)
    series = (("e_lat", 100.0, "e_lat [cm]", "tab:blue",
               "lateral error (+: left of the reference heading)"),
              ("e_lon", 100.0, "e_lon [cm]", "tab:purple",
               "longitudinal error (+: ahead along the reference heading, toward the robot)"),
              ("e_theta", 180.0 / math.pi, "e_theta [deg]", "tab:green",
               "heading error theta_n - theta_d"))
    disturbance = _intervals(t, _disturbance_mask(data))
    for ax, (name, scale, ylabel, color, what) in zip(axes, series):
        for value, shade, label in _DIRECTION_BANDS:
            _shade(ax, _intervals(t, direction == value), shade, 1.0, label=label, zorder=0,
                   gid=f"direction{int(value):+d}")
        _shade(ax, disturbance, _C_DIST, 0.25, label="disturbance (push/slide)", zorder=0.5)
        e = _col(data, name) * scale
        unit = ylabel.split("[")[1].rstrip("]")
        ax.plot(t, e, "-", color=color, lw=1.4, gid=name,
                label=f"RMS {_rms(e):.2f} {unit}, max |.| {np.max(np.abs(e)):.2f} {unit}, "
                      f"final {e[-1]:.2f} {unit}")
        ax.axhline(0.0, color="0.3", lw=0.6)
        ax.set_ylabel(ylabel)
        ax.set_title(what, fontsize=9)
        ax.grid(True, lw=0.4, alpha=0.5)
        ax.legend(handles=[ax.get_lines()[0]], loc="best", fontsize=8)
    axes[-1].set_xlabel("time t [s]")
    axes[0].set_xlim(t[0], t[-1] if t[-1] > t[0] else t[0] + 1.0)
    present = [(Patch(color=shade), label) for value, shade, label in _DIRECTION_BANDS
               if np.any(direction == value)]
    if disturbance:
        present.append((Patch(color=_C_DIST, alpha=0.25), "disturbance (push/slide)"))
    if present:
        fig.legend(*zip(*present), loc="outside lower center", ncol=len(present), fontsize=8,
                   title="background: reference direction", title_fontsize=8, frameon=False)
    fig.suptitle("Tracking error of the last trailer (in the reference's frame)")
    return fig


def plot_tracking_error(data, n: int, out_path) -> Path:
    """Lateral and longitudinal errors [cm] and heading error [deg] of the last trailer over time,
    with the reference direction (push/pull/rest) as background bands. Returns the written path."""
    path = _output_path(out_path)
    return _save(tracking_error_figure(data, n), path)


# ---------------------------------------------------------------------------------------------
# 4. lateral forces
# ---------------------------------------------------------------------------------------------
_SEPARATE_FORCE_PANELS = 4  # up to this many trailers: one panel each


def lateral_forces_figure(data, n: int) -> Figure:
    """The figure of :func:`plot_lateral_forces`, unsaved.

    Line gids: ``F_lat{i}`` (|F_lat_i| [N]) and ``F_lat_max{i}`` (friction limit); slip spans
    carry gid ``slip{i}``.
    """
    cols = ["t"] + [f"{b}{i}" for b in ("F_lat", "F_lat_max", "slipping") for i in range(1, n + 1)]
    n = _check_data(data, n, cols)
    t = _col(data, "t")
    force = [np.abs(_col(data, f"F_lat{i}")) for i in range(1, n + 1)]
    limit = [_col(data, f"F_lat_max{i}") for i in range(1, n + 1)]
    slips = [_intervals(t, _col(data, f"slipping{i}") > 0.5) for i in range(1, n + 1)]
    xmax = t[-1] if t[-1] > t[0] else t[0] + 1.0

    def ratio(i):
        lim = np.max(limit[i])
        return float(np.max(force[i]) / lim) if lim > 0 else float("nan")

    if n <= _SEPARATE_FORCE_PANELS:
        fig = _new_figure(8.0, 1.2 + 2.0 * n)
        axes = np.atleast_1d(fig.subplots(n, 1, sharex=True, squeeze=False)[:, 0])
        for i, ax in enumerate(axes):
            for k, (a, b) in enumerate(slips[i]):
                ax.axvspan(a, b, color=_C_SLIP, alpha=0.3, lw=0, gid=f"slip{i + 1}",
                           label="wheel slipping" if k == 0 else None)
            ax.plot(t, force[i], "-", color="tab:blue", lw=1.3, label=f"|F_lat,{i + 1}|",
                    gid=f"F_lat{i + 1}")
            ax.plot(t, limit[i], "--", color="tab:red", lw=1.3,
                    label=f"friction limit {np.max(limit[i]):.1f} N", gid=f"F_lat_max{i + 1}")
            ax.set_ylim(0.0, 1.15 * max(np.max(force[i]), np.max(limit[i]), 1e-9))
            ax.set_ylabel(f"|F_lat,{i + 1}| [N]")
            ax.set_title(f"trailer {i + 1}: peak {np.max(force[i]):.1f} N = "
                         f"{100 * ratio(i):.0f} % of the limit, "
                         f"{len(slips[i])} slip interval{'s' if len(slips[i]) != 1 else ''}",
                         fontsize=9)
            ax.grid(True, lw=0.4, alpha=0.5)
            ax.legend(loc="upper right", fontsize=8)
        axes[-1].set_xlabel("time t [s]")
        axes[0].set_xlim(t[0], xmax)
    else:
        fig = _new_figure(8.5, 7.0)
        ax, ax_slip = fig.subplots(2, 1, sharex=True, height_ratios=(2.2, 1.0))
        colors = _series_colors(n, categorical=False)
        for i in range(n):
            ax.plot(t, force[i], "-", color=colors[i], lw=1.0, gid=f"F_lat{i + 1}")
            ax.plot(t, limit[i], "--", color=colors[i] if np.ptp([np.max(v) for v in limit]) > 0
                    else "tab:red", lw=1.2, gid=f"F_lat_max{i + 1}")
            for a, b in slips[i]:
                ax_slip.broken_barh([(a, max(b - a, 1e-9))], (i + 0.6, 0.8), color=_C_SLIP,
                                    gid=f"slip{i + 1}")
        worst = int(np.nanargmax([ratio(i) for i in range(n)]))
        ax.set_ylabel("|F_lat,i| [N]")
        ax.set_title(f"Lateral wheel force of each trailer (dashed: friction limit); highest "
                     f"peak: trailer {worst + 1}, {100 * ratio(worst):.0f} % of its limit",
                     fontsize=9)
        ax.grid(True, lw=0.4, alpha=0.5)
        _index_colorbar(fig, ax, colors, "trailer index i")
        ax_slip.set_ylim(0.5, n + 0.5)
        ax_slip.set_ylabel("trailer i")
        ax_slip.set_title("wheel slipping intervals", fontsize=9)
        ax_slip.grid(True, lw=0.4, alpha=0.5)
        ax_slip.set_xlabel("time t [s]")
        ax.set_xlim(t[0], xmax)
    fig.suptitle("Lateral wheel forces against the friction limit μ (m + payload) g")
    return fig


def plot_lateral_forces(data, n: int, out_path) -> Path:
    """|F_lat_i| of every trailer over time against its friction limit (dashed), with the slip
    intervals shaded (one panel per trailer up to 4 trailers, one panel and a slip timeline
    beyond). Returns the written path."""
    path = _output_path(out_path)
    return _save(lateral_forces_figure(data, n), path)


# ---------------------------------------------------------------------------------------------
# 5. animation
# ---------------------------------------------------------------------------------------------
class _BlitGifWriter(PillowWriter):
    """A PillowWriter that renders the static background once and then draws only the moving
    ``artists`` on it (blitting), and maps every frame onto one shared 256-colour palette
    (built from the first and last frames and ``colors``) instead of quantizing each frame."""

    def __init__(self, artists: Sequence, fps: float, colors: Sequence = ()):
        super().__init__(fps=fps)
        self._artists = list(artists)
        self._colors = list(colors)
        self._background = None

    def setup(self, fig, outfile, dpi=None):
        super().setup(fig, outfile, dpi=dpi)
        self._background = None

    def grab_frame(self, **savefig_kwargs):
        canvas = self.fig.canvas
        if self._background is None:
            shown = [a.get_visible() for a in self._artists]
            for a in self._artists:
                a.set_visible(False)
            canvas.draw()
            self._background = canvas.copy_from_bbox(self.fig.bbox)
            for a, vis in zip(self._artists, shown):
                a.set_visible(vis)
        canvas.restore_region(self._background)
        for a in self._artists:
            a.axes.draw_artist(a)
        width, height = canvas.get_width_height()
        frame = Image.frombuffer("RGBA", (width, height), bytes(canvas.buffer_rgba()), "raw",
                                 "RGBA", 0, 1)
        self._frames.append(frame.convert("RGB"))

    def finish(self):
        if not self._frames:
            raise PlotError("the animation has no frames")
        first, last = self._frames[0], self._frames[-1]
        width, height = first.size
        swatch = 16
        sheet = Image.new("RGB", (width, 2 * height + swatch), "white")
        sheet.paste(first, (0, 0))
        sheet.paste(last, (0, height))
        for k, color in enumerate(self._colors):
            rgb = tuple(int(round(255 * c)) for c in to_rgb(color))
            sheet.paste(rgb, (k * swatch, 2 * height, (k + 1) * swatch, 2 * height + swatch))
        palette = sheet.quantize(colors=256, method=Image.Quantize.MEDIANCUT)
        frames = [f.quantize(palette=palette, dither=Image.Dither.NONE) for f in self._frames]
        frames[0].save(self.outfile, save_all=True, append_images=frames[1:],
                       duration=max(int(round(1000.0 / self.fps)), 10), loop=0)


def animate(data, n: int, out_path, *, world=None, footprints=None, fps: float = 10,
            max_frames: int = 150, path_xy=None, geometry=None) -> Path:
    """Animated GIF of the train moving along its reference (top view).

    Parameters
    ----------
    data, n
        As in :func:`plot_map`.
    out_path : path-like
        ``.gif`` file, written atomically.
    world, footprints, path_xy, geometry
        As in :func:`plot_map`.
    fps : float
        Frames per second of the GIF (> 0).
    max_frames : int
        At most this many frames, evenly spread over the run (>= 1).

    Returns
    -------
    pathlib.Path
        ``out_path``.
    """
    gif_path = _output_path(out_path, allowed=("gif",))
    if (isinstance(fps, bool) or not isinstance(fps, (int, float))
            or not (math.isfinite(fps) and fps > 0)):
        raise PlotError(f"fps = {fps!r}: need a finite number > 0")
    n = _check_data(data, n, _pose_columns(n) + ["x_d", "y_d", "theta_d"])
    frames = frame_indices(len(data), max_frames)
    bodies = _footprints(footprints, n)
    front, _rear = hitch_links(data, n, geometry)
    t = _col(data, "t")
    x, y, th = _bodies(data, n)
    xd, yd = _col(data, "x_d"), _col(data, "y_d")
    names = data.dtype.names
    slipping = np.stack([_col(data, f"slipping{i}") > 0.5 if f"slipping{i}" in names
                         else np.zeros(len(data), bool) for i in range(1, n + 1)], axis=1)
    jack = _col(data, "jackknifed") > 0.5 if "jackknifed" in names else np.zeros(len(data), bool)
    path = None
    if path_xy is not None:
        path = np.asarray(path_xy, dtype=float)
        if path.ndim != 2 or path.shape[1] < 2:
            raise PlotError(f"path_xy has shape {path.shape}: need (m, 2) points [m]")
        path = path[:, :2]

    all_corners = [body_corners(x[frames, i], y[frames, i], th[frames, i], *bodies[i])
                   for i in range(n + 1)]  # each (frames, 4, 2)
    extent = _extent([np.stack([x.ravel(), y.ravel()], axis=1), np.stack([xd, yd], axis=1), path,
                      *all_corners], world)
    size, extent = _map_size(extent, 6.6, 0.7, 0.9, lo=2.6, hi=6.5)
    fig = _new_figure(*size, dpi=GIF_DPI)
    ax = fig.add_subplot()
    if world is not None:
        world.plot(ax)
    if path is not None:
        ax.plot(path[:, 0], path[:, 1], "-", color=_C_PATH, lw=2.5, alpha=0.6)
    ax.plot(xd, yd, "--", color=_C_REF, lw=1.0)
    ax.plot([xd[-1]], [yd[-1]], "*", color="tab:green", mec="black", ms=12, zorder=7)
    robot_trace, = ax.plot([], [], "-", color=_C_ROBOT, lw=1.2, label="robot")
    last_trace, = ax.plot([], [], "-", color=_C_LAST, lw=1.2, label=f"last trailer ({n})")
    target, = ax.plot([], [], "x", color=_C_REF, ms=7, mew=1.5, zorder=9, label="reference point")
    patches = []
    for i in range(n + 1):
        face = "#e8a3a3" if i == 0 else "#b9cde3"
        edge = "#8b1a1a" if i == 0 else "#1f4e79"
        patch = PolygonPatch(all_corners[i][0], closed=True, facecolor=face, edgecolor=edge,
                             lw=1.2, alpha=0.85, zorder=5)
        ax.add_patch(patch)
        patches.append(patch)
    train, = ax.plot([], [], "-o", color="0.15", lw=1.3, ms=2.5, zorder=6)
    stamp = ax.text(0.01, 0.99, "", transform=ax.transAxes, va="top", ha="left", fontsize=9,
                    family="monospace", bbox={"facecolor": "white", "alpha": 0.8, "lw": 0})
    _equal_limits(ax, extent)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.legend(loc="upper right", fontsize=7, framealpha=0.8)
    ax.set_title(f"Robot with {n} trailer{'s' if n > 1 else ''} (orange: wheel slipping)",
                 fontsize=10)
    dt = np.diff(t[frames])
    digits = int(np.clip(math.ceil(-math.log10(dt.min())) if dt.size and dt.min() > 0 else 1, 1, 4))

    def draw(frame: int, r: int) -> None:
        robot_trace.set_data(x[: r + 1, 0], y[: r + 1, 0])
        last_trace.set_data(x[: r + 1, n], y[: r + 1, n])
        target.set_data([xd[r]], [yd[r]])
        for i, patch in enumerate(patches):
            patch.set_xy(all_corners[i][frame])
            if i > 0:
                patch.set_facecolor(_C_SLIP if slipping[r, i - 1] else "#b9cde3")
        train.set_data(*_train_polyline(x[r], y[r], th[r], front))
        phis = np.degrees(th[r, :-1] - th[r, 1:])
        phis = (phis + 180.0) % 360.0 - 180.0
        text = f"t = {t[r]:.{digits}f} s   max|phi| = {np.max(np.abs(phis)):5.1f} deg"
        if jack[r]:
            text += "   JACKKNIFED"
        stamp.set_text(text)

    draw(0, int(frames[0]))
    fig.canvas.draw()  # lay the figure out once, then keep that layout for every frame
    fig.set_layout_engine("none")
    start = _time.perf_counter()
    writer = _BlitGifWriter([robot_trace, last_trace, *patches, train, target, stamp], fps=fps,
                            colors=[_C_SLIP, _C_ROBOT, _C_LAST, "#e8a3a3", "#b9cde3", "#8b1a1a",
                                    "#1f4e79", "0.15"])

    def write(partial: Path) -> None:
        with writer.saving(fig, str(partial), dpi=GIF_DPI):
            for frame, r in enumerate(frames):
                draw(frame, int(r))
                writer.grab_frame()

    _atomic(gif_path, write)
    log.debug("wrote %s: %d frames in %.2f s", gif_path, len(frames), _time.perf_counter() - start)
    return gif_path


# ---------------------------------------------------------------------------------------------
# 6. everything
# ---------------------------------------------------------------------------------------------
def plot_all(result_or_data, n: int, out_dir, *, world=None, path_xy=None, footprints=None,
             gif: bool = True, geometry=None) -> list[Path]:
    """Write ``map.png``, ``inputs_joints.png``, ``tracking_error.png``, ``lateral_forces.png``
    and (if ``gif``) ``train.gif`` into ``out_dir``.

    Parameters
    ----------
    result_or_data : Result or numpy structured array
        A :class:`~pushtrain.cosim.master.Result` (its status goes into the map's title) or its
        ``data``.
    n : int
        Number of trailers (must match ``Result.n_trailers``).
    out_dir : path-like
        Output folder (created if missing).
    world, path_xy, footprints, geometry
        As in :func:`plot_map`.
    gif : bool
        Also write the animation.

    Returns
    -------
    list of pathlib.Path
        The written files, in the order above.
    """
    n = _check_n(n)
    # a numpy array has a .data attribute too (its buffer): only unwrap Result-like objects
    is_array = isinstance(result_or_data, np.ndarray)
    data = result_or_data if is_array else getattr(result_or_data, "data", result_or_data)
    n_result = None if is_array else getattr(result_or_data, "n_trailers", None)
    if n_result is not None and n_result != n:
        raise PlotError(f"n = {n} but the result has n_trailers = {n_result}")
    title = None
    status = None if is_array else getattr(result_or_data, "status", None)
    if status is not None:
        title = f"Robot with {n} trailer{'s' if n > 1 else ''}: {status.replace('_', ' ')}"
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    start = _time.perf_counter()
    written = [
        plot_map(data, n, out / "map.png", world=world, path_xy=path_xy, footprints=footprints,
                 title=title, geometry=geometry),
        plot_inputs_and_joints(data, n, out / "inputs_joints.png"),
        plot_tracking_error(data, n, out / "tracking_error.png"),
        plot_lateral_forces(data, n, out / "lateral_forces.png"),
    ]
    if gif:
        written.append(animate(data, n, out / "train.gif", world=world, footprints=footprints,
                               path_xy=path_xy, geometry=geometry))
    log.info("wrote %d plot files to %s in %.1f s", len(written), out, _time.perf_counter() - start)
    return written
