"""Animated GIF of the train moving along its reference (top view).

The walls, path and reference are rendered once; each frame redraws only the moving artists on
that background (blitting) and maps onto one shared 256-colour palette.
"""

from __future__ import annotations

import logging
import math
import time as _time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.animation import PillowWriter
from matplotlib.colors import to_rgb
from matplotlib.patches import Polygon as PolygonPatch
from PIL import Image

from pushtrain.errors import PlotError
from pushtrain.report.common import (
    C_LAST,
    C_PATH,
    C_REF,
    C_ROBOT,
    C_SLIP,
    GIF_DPI,
    atomic,
    col,
    new_figure,
    output_path,
)
from pushtrain.report.geometry import (
    TopView,
    body_corners,
    equal_limits,
    extent_of,
    frame_indices,
    map_size,
    top_view,
    train_polyline,
)

__all__ = ["animate"]

log = logging.getLogger(__name__)

_ROBOT_FACE, _ROBOT_EDGE = "#e8a3a3", "#8b1a1a"
_TRAILER_FACE, _TRAILER_EDGE = "#b9cde3", "#1f4e79"
_TRAIN_LINE = "0.15"
_PALETTE_COLORS = (C_SLIP, C_ROBOT, C_LAST, _ROBOT_FACE, _TRAILER_FACE, _ROBOT_EDGE,
                   _TRAILER_EDGE, _TRAIN_LINE)
"""Colours guaranteed a place in the GIF's shared palette."""


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
            for a, vis in zip(self._artists, shown, strict=True):
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
        palette = self._palette()
        frames = [f.quantize(palette=palette, dither=Image.Dither.NONE) for f in self._frames]
        frames[0].save(self.outfile, save_all=True, append_images=frames[1:],
                       duration=max(round(1000.0 / self.fps), 10), loop=0)

    def _palette(self) -> Image.Image:
        """A 256-colour palette of the first and last frames and a swatch of ``colors``."""
        first, last = self._frames[0], self._frames[-1]
        width, height = first.size
        swatch = 16
        sheet = Image.new("RGB", (width, 2 * height + swatch), "white")
        sheet.paste(first, (0, 0))
        sheet.paste(last, (0, height))
        for k, color in enumerate(self._colors):
            rgb = tuple(round(255 * c) for c in to_rgb(color))
            sheet.paste(rgb, (k * swatch, 2 * height, (k + 1) * swatch, 2 * height + swatch))
        return sheet.quantize(colors=256, method=Image.Quantize.MEDIANCUT)


class _TrainScene:
    """The animation's figure: static walls, path and reference, and the artists that move
    (traces, reference point, bodies, hitch line, time stamp), set for one row by :meth:`draw`."""

    def __init__(self, run: TopView, data, frames: np.ndarray, world=None):
        self.run = run
        n = run.n
        names = data.dtype.names
        self.slipping = np.stack([col(data, f"slipping{i}") > 0.5 if f"slipping{i}" in names
                                  else np.zeros(len(data), bool) for i in range(1, n + 1)], axis=1)
        self.jack = (col(data, "jackknifed") > 0.5 if "jackknifed" in names
                     else np.zeros(len(data), bool))
        self.corners = [body_corners(run.x[frames, i], run.y[frames, i], run.th[frames, i],
                                     *run.bodies[i]) for i in range(n + 1)]  # each (frames, 4, 2)
        extent = extent_of([np.stack([run.x.ravel(), run.y.ravel()], axis=1),
                            np.stack([run.xd, run.yd], axis=1), run.path, *self.corners], world)
        size, extent = map_size(extent, 6.6, 0.7, 0.9, lo=2.6, hi=6.5)
        self.fig = new_figure(*size, dpi=GIF_DPI)
        ax = self.fig.add_subplot()
        if world is not None:
            world.plot(ax)
        self._add_static(ax)
        self._add_moving(ax)
        equal_limits(ax, extent)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.grid(True, lw=0.4, alpha=0.5)
        ax.legend(loc="upper right", fontsize=7, framealpha=0.8)
        ax.set_title(f"Robot with {n} trailer{'s' if n > 1 else ''} (orange: wheel slipping)",
                     fontsize=10)
        dt = np.diff(run.t[frames])
        self.digits = int(np.clip(math.ceil(-math.log10(dt.min()))
                                  if dt.size and dt.min() > 0 else 1, 1, 4))

    def _add_static(self, ax) -> None:
        run = self.run
        if run.path is not None:
            ax.plot(run.path[:, 0], run.path[:, 1], "-", color=C_PATH, lw=2.5, alpha=0.6)
        ax.plot(run.xd, run.yd, "--", color=C_REF, lw=1.0)
        ax.plot([run.xd[-1]], [run.yd[-1]], "*", color="tab:green", mec="black", ms=12, zorder=7)

    def _add_moving(self, ax) -> None:
        self.robot_trace, = ax.plot([], [], "-", color=C_ROBOT, lw=1.2, label="robot")
        self.last_trace, = ax.plot([], [], "-", color=C_LAST, lw=1.2,
                                   label=f"last trailer ({self.run.n})")
        self.target, = ax.plot([], [], "x", color=C_REF, ms=7, mew=1.5, zorder=9,
                               label="reference point")
        self.patches = []
        for i, corners in enumerate(self.corners):
            patch = PolygonPatch(corners[0], closed=True,
                                 facecolor=_ROBOT_FACE if i == 0 else _TRAILER_FACE,
                                 edgecolor=_ROBOT_EDGE if i == 0 else _TRAILER_EDGE,
                                 lw=1.2, alpha=0.85, zorder=5)
            ax.add_patch(patch)
            self.patches.append(patch)
        self.train, = ax.plot([], [], "-o", color=_TRAIN_LINE, lw=1.3, ms=2.5, zorder=6)
        self.stamp = ax.text(0.01, 0.99, "", transform=ax.transAxes, va="top", ha="left",
                             fontsize=9, family="monospace",
                             bbox={"facecolor": "white", "alpha": 0.8, "lw": 0})

    @property
    def moving(self) -> list:
        """The artists that change from frame to frame."""
        return [self.robot_trace, self.last_trace, *self.patches, self.train, self.target,
                self.stamp]

    def draw(self, frame: int, r: int) -> None:
        """Set the moving artists to frame number ``frame``, which shows data row ``r``."""
        run, n = self.run, self.run.n
        x, y, th = run.x, run.y, run.th
        self.robot_trace.set_data(x[: r + 1, 0], y[: r + 1, 0])
        self.last_trace.set_data(x[: r + 1, n], y[: r + 1, n])
        self.target.set_data([run.xd[r]], [run.yd[r]])
        for i, patch in enumerate(self.patches):
            patch.set_xy(self.corners[i][frame])
            if i > 0:
                patch.set_facecolor(C_SLIP if self.slipping[r, i - 1] else _TRAILER_FACE)
        self.train.set_data(*train_polyline(x[r], y[r], th[r], run.front))
        phis = np.degrees(th[r, :-1] - th[r, 1:])
        phis = (phis + 180.0) % 360.0 - 180.0
        text = f"t = {run.t[r]:.{self.digits}f} s   max|phi| = {np.max(np.abs(phis)):5.1f} deg"
        if self.jack[r]:
            text += "   JACKKNIFED"
        self.stamp.set_text(text)


def animate(data, n: int, out_path, *, world=None, footprints=None, fps: float = 10,
            max_frames: int = 150, path_xy=None, geometry=None) -> Path:
    """Animated GIF of the train moving along its reference (top view).

    Parameters
    ----------
    data, n
        As in :func:`~pushtrain.report.mapview.plot_map`.
    out_path : path-like
        ``.gif`` file, written atomically.
    world, footprints, path_xy, geometry
        As in :func:`~pushtrain.report.mapview.plot_map`.
    fps : float
        Frames per second of the GIF (> 0).
    max_frames : int
        At most this many frames, evenly spread over the run (>= 1).

    Returns
    -------
    pathlib.Path
        ``out_path``.
    """
    gif_path = output_path(out_path, allowed=("gif",))
    if (isinstance(fps, bool) or not isinstance(fps, (int, float))
            or not (math.isfinite(fps) and fps > 0)):
        raise PlotError(f"fps = {fps!r}: need a finite number > 0")
    run = top_view(data, n, footprints=footprints, geometry=geometry, path_xy=path_xy,
                   min_path_points=0)
    frames = frame_indices(len(data), max_frames)
    scene = _TrainScene(run, data, frames, world)
    scene.draw(0, int(frames[0]))
    scene.fig.canvas.draw()  # lay the figure out once, then keep that layout for every frame
    scene.fig.set_layout_engine("none")
    start = _time.perf_counter()
    writer = _BlitGifWriter(scene.moving, fps=fps, colors=_PALETTE_COLORS)

    def write(partial: Path) -> None:
        with writer.saving(scene.fig, str(partial), dpi=GIF_DPI):
            for frame, r in enumerate(frames):
                scene.draw(frame, int(r))
                writer.grab_frame()

    atomic(gif_path, write)
    log.debug("wrote %s: %d frames in %.2f s", gif_path, len(frames), _time.perf_counter() - start)
    return gif_path
