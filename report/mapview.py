"""The top view of a run (the paper's Fig. 9/11/13): walls, planned path, reference, traces of the
robot and the last trailer, train snapshots fading from light (early) to dark (late), start and
goal, slip and jackknife marks."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from matplotlib.patches import Polygon as PolygonPatch

from pushtrain.report.common import (
    C_JACK,
    C_LAST,
    C_PATH,
    C_REF,
    C_ROBOT,
    C_SLIP,
    SNAPSHOT_CMAP,
    new_figure,
    output_path,
    save,
)
from pushtrain.report.data import col
from pushtrain.report.geometry import (
    TopView,
    body_corners,
    equal_limits,
    extent_of,
    map_size,
    spaced_snapshots,
    top_view,
    train_polyline,
    wheel_segments,
)

__all__ = ["map_figure", "plot_map"]


def map_figure(data, n: int, *, world=None, path_xy=None, footprints=None, snapshots: int = 8,
               title: str | None = None, geometry=None) -> Figure:
    """The top view of :func:`plot_map` as an unsaved Figure.

    At most ``snapshots`` snapshots, spread by distance travelled and none covering another by
    more than a quarter (:func:`~pushtrain.report.geometry.spaced_snapshots`; the figure's
    ``snapshot_rows`` attribute lists their rows). Their artists carry gids
    ``"snapshot{k}:body{i}"`` (rectangles) and ``"snapshot{k}:train"`` (the line
    P_0 -> H_1 -> P_1 -> ... -> P_n through the hitch points).
    """
    run = top_view(data, n, footprints=footprints, geometry=geometry, path_xy=path_xy)
    idx = spaced_snapshots(run.x, run.y, run.th, run.bodies, snapshots)
    corners = {(k, i): body_corners(run.x[r, i], run.y[r, i], run.th[r, i], *run.bodies[i])
               for k, r in enumerate(idx) for i in range(run.n + 1)}
    goal_box = body_corners(run.xd[-1], run.yd[-1], run.thd[-1], *run.bodies[run.n])
    extent = extent_of([np.stack([run.x.ravel(), run.y.ravel()], axis=1),
                        np.stack([run.xd, run.yd], axis=1), run.path, goal_box,
                        *corners.values()], world)
    size, extent = map_size(extent, 6.8, 2.6, 1.5)
    fig = new_figure(*size, fixed_aspect=True)
    ax = fig.add_subplot()
    if world is not None:
        world.plot(ax)
    _draw_paths(ax, run)
    t = run.t
    norm = Normalize(vmin=t[0], vmax=t[-1] if t[-1] > t[0] else t[0] + 1.0)
    for k, r in enumerate(idx):
        _draw_snapshot(ax, run, k, r, corners, color=SNAPSHOT_CMAP(norm(t[r])),
                       z=5 + k / max(len(idx), 1))
    _draw_ends(ax, run, goal_box)
    _draw_events(ax, data, run)
    fig.snapshot_rows = idx
    _finish(fig, ax, extent, len(idx), norm, title or
            f"Backward motion of a robot with {run.n} trailer{'s' if run.n > 1 else ''}: "
            f"top view ({t[-1] - t[0]:.1f} s)")
    return fig


def _draw_paths(ax, run: TopView) -> None:
    """Planned path, reference and the traces of the last trailer and the robot."""
    n = run.n
    if run.path is not None:  # a wide pale band, seen around the reference and trace on it
        ax.plot(run.path[:, 0], run.path[:, 1], "-", color=C_PATH, lw=9.0, alpha=0.35,
                solid_capstyle="round", zorder=2, label="planned path (last trailer)")
    ax.plot(run.xd, run.yd, "--", color=C_REF, lw=1.3, zorder=22, label="reference (last trailer)")
    ax.plot(run.x[:, n], run.y[:, n], "-", color=C_LAST, lw=1.8, zorder=21,
            label=f"last trailer ({n}) trace")
    ax.plot(run.x[:, 0], run.y[:, 0], "-", color=C_ROBOT, lw=1.8, zorder=21, label="robot trace")


def _draw_snapshot(ax, run: TopView, k: int, r: int, corners: dict, color, z: float) -> None:
    """Snapshot ``k`` at row ``r``: bodies, wheels, the line through the hitches, robot heading."""
    x, y, th = run.x, run.y, run.th
    for i in range(run.n + 1):  # every body filled alike (its time's colour); the robot's
        # outline is red, so the robot stands out without looking later than its trailers
        patch = PolygonPatch(corners[(k, i)], closed=True, facecolor=color, alpha=0.45,
                             edgecolor="none", zorder=z)
        patch.set_gid(f"snapshot{k}:body{i}")
        ax.add_patch(patch)
        ax.add_patch(PolygonPatch(corners[(k, i)], closed=True, fill=False,
                                  edgecolor=C_ROBOT if i == 0 else color,
                                  lw=1.6 if i == 0 else 0.8, zorder=z))
        if i > 0:
            for seg in wheel_segments(x[r, i], y[r, i], th[r, i], run.bodies[i][1]):
                ax.plot(*zip(*seg, strict=True), "-", color=color, lw=2.6, solid_capstyle="butt",
                        zorder=z)
    px, py = train_polyline(x[r], y[r], th[r], run.front)
    (line,) = ax.plot(px, py, "-", color=color, lw=1.2, zorder=z + 0.01)
    line.set_gid(f"snapshot{k}:train")
    ax.plot(px[1::2], py[1::2], "o", ms=2.5, color=color, zorder=z + 0.01)  # hitch points
    # robot heading: a red tick from its centre to its front edge
    head = 0.5 * run.bodies[0][0] + run.bodies[0][2]
    ax.plot([x[r, 0], x[r, 0] + head * math.cos(th[r, 0])],
            [y[r, 0], y[r, 0] + head * math.sin(th[r, 0])], "-", color=C_ROBOT, lw=1.6,
            zorder=z + 0.02)


def _draw_ends(ax, run: TopView, goal_box: np.ndarray) -> None:
    """Goal pose box, start of the last trailer and the end of the reference."""
    n = run.n
    ax.add_patch(PolygonPatch(goal_box, closed=True, fill=False, edgecolor="tab:green", lw=1.4,
                              ls="--", zorder=23, label="goal pose (last trailer)"))
    ax.plot([run.x[0, n]], [run.y[0, n]], "o", color="tab:green", mec="black", ms=9, zorder=24,
            label="start (last trailer)")
    ax.plot([run.xd[-1]], [run.yd[-1]], "*", color="tab:green", mec="black", ms=14, zorder=24,
            label="goal (reference end)")


def _draw_events(ax, data, run: TopView) -> None:
    """Crosses where a wheel slips and a mark where the train first jackknifes."""
    n, x, y = run.n, run.x, run.y
    names = data.dtype.names
    slip_x, slip_y = [], []
    for i in range(1, n + 1):
        if f"slipping{i}" in names:
            m = col(data, f"slipping{i}") > 0.5
            slip_x.append(x[m, i])
            slip_y.append(y[m, i])
    if slip_x and sum(a.size for a in slip_x):
        ax.plot(np.concatenate(slip_x), np.concatenate(slip_y), "x", color=C_SLIP, ms=4,
                mew=1.0, zorder=25, label="wheel slipping")
    if "jackknifed" in names and np.any(col(data, "jackknifed") > 0.5):
        j = int(np.flatnonzero(col(data, "jackknifed") > 0.5)[0])
        ax.plot([x[j, n]], [y[j, n]], "X", color=C_JACK, mec="black", ms=12, zorder=26,
                label=f"jackknife (t = {run.t[j]:.1f} s)")


def _finish(fig, ax, extent, snapshots: int, norm, title: str) -> None:
    """Limits, labels, the legend beside the axes, the snapshot-time colour bar and the title."""
    equal_limits(ax, extent)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, lw=0.4, alpha=0.5)
    handles, labels = ax.get_legend_handles_labels()
    if snapshots:
        shade = SNAPSHOT_CMAP(0.6)
        handles.append(Patch(facecolor=shade, edgecolor=C_ROBOT, alpha=0.6, lw=1.6))
        labels.append("robot (red outline, tick: its heading)")
        handles.append(Patch(facecolor=shade, edgecolor=shade, alpha=0.6))
        labels.append(f"trailers; train in {snapshots} snapshots")
    ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8,
              frameon=False)
    if snapshots:
        bar = fig.colorbar(ScalarMappable(norm=norm, cmap=SNAPSHOT_CMAP), ax=ax, location="bottom",
                           shrink=0.6, aspect=35, pad=0.02)
        bar.set_label("snapshot time t [s]")
    ax.set_title(title)


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
        Walls and free space (:class:`pushtrain.facility.free_space.World`).
    path_xy : array of shape (m, 2), optional
        The planned dense path of the last trailer [m].
    footprints : dict, optional
        ``'robot'`` and ``'trailer'`` (one size for all) or ``'trailers'`` (n entries), each
        ``(length, width)`` or ``(length, width, offset)`` [m] or an object with those attributes;
        default :data:`~pushtrain.report.geometry.DEFAULT_FOOTPRINTS`.
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
    path = output_path(out_path)
    return save(map_figure(data, n, world=world, path_xy=path_xy, footprints=footprints,
                           snapshots=snapshots, title=title, geometry=geometry), path)
