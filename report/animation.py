"""Animated GIF of the train moving along its reference (top view).

The walls, path, reference and legend are rendered once; each frame redraws only the moving
artists on that background (blitting). Frames go straight to the file as they are drawn
(:class:`_GifStream`): each is mapped onto one shared 256-colour palette and stored as the
rectangle in which it differs from the frame before, so memory holds two frames, not all of them.
"""

from __future__ import annotations

import logging
import math
import struct
import time as _time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.colors import to_rgb
from matplotlib.patches import Polygon as PolygonPatch
from PIL import GifImagePlugin, Image, ImageDraw, ImageFont

from pushtrain.errors import PlotError
from pushtrain.report.common import (
    C_LAST,
    C_PATH,
    C_REF,
    C_ROBOT,
    C_SLIP,
    GIF_DPI,
    atomic,
    new_figure,
    output_path,
)
from pushtrain.report.data import col
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


class _Blitter:
    """Frames of ``fig`` drawn on a kept background (blitting).

    The figure is rendered once without the ``artists`` that move; each frame :meth:`restore` s
    that background and draws the moving artists on it. Artists drawn before :meth:`keep` become
    part of the background (the traces, which only grow, are drawn one new piece at a time).
    """

    def __init__(self, fig, artists: Sequence):
        self.fig, self.canvas = fig, fig.canvas
        shown = [a.get_visible() for a in artists]
        for a in artists:
            a.set_visible(False)
        self.canvas.draw()
        self.keep()
        for a, vis in zip(artists, shown, strict=True):
            a.set_visible(vis)

    def restore(self) -> None:
        self.canvas.restore_region(self.background)

    def keep(self) -> None:
        """Make what the canvas shows now the background."""
        self.background = self.canvas.copy_from_bbox(self.fig.bbox)

    @staticmethod
    def draw(artists: Sequence) -> None:
        for a in artists:
            a.axes.draw_artist(a)

    def pixels(self) -> np.ndarray:
        """The canvas: (height, width, 4) RGBA uint8, a view that the next frame overwrites."""
        return np.asarray(self.canvas.buffer_rgba())


_TRANSPARENT = 255
"""Palette index of the GIF's transparent colour: a frame's pixels that did not change."""


def _rgb(rgba: np.ndarray) -> Image.Image:
    """An RGB image of a (height, width, 4) uint8 array (alpha dropped)."""
    return Image.fromarray(np.ascontiguousarray(rgba)).convert("RGB")


def _palette(first: np.ndarray, last: np.ndarray, colors: Sequence) -> Image.Image:
    """A palette ("P" image) of 255 colours from the first and last frames (RGBA arrays) and a
    swatch of ``colors``; index 255 is left for :data:`_TRANSPARENT`."""
    height, width = first.shape[:2]
    swatch = 16
    sheet = Image.new("RGB", (width, 2 * height + swatch), "white")
    sheet.paste(_rgb(first), (0, 0))
    sheet.paste(_rgb(last), (0, height))
    for k, color in enumerate(colors):
        rgb = tuple(round(255 * c) for c in to_rgb(color))
        sheet.paste(rgb, (k * swatch, 2 * height, (k + 1) * swatch, 2 * height + swatch))
    return sheet.quantize(colors=_TRANSPARENT, method=Image.Quantize.MEDIANCUT)


class _GifStream:
    """An animated GIF (GIF89a, looping) written to ``fp`` one frame at a time.

    Every frame is mapped onto ``palette`` (nearest colour, no dithering) and stored as the
    smallest rectangle holding its changes from the previous frame, drawn over it (disposal
    "do not dispose"), with the unchanged pixels in it transparent; a frame equal to the
    previous one lengthens that one's display time. A frame is written when the next one
    arrives (or on :meth:`close`), so at most two are held. Each frame shows for ``duration``
    [ms], rounded to the GIF's unit of 10 ms.
    """

    def __init__(self, fp, palette: Image.Image, duration: float):
        self.fp, self.palette = fp, palette
        self.duration = max(round(duration / 10.0), 1) * 10
        self.previous: np.ndarray | None = None  # the frame so far, (height, width) uint32 RGBA
        self.pending: list | None = None  # [P image, (x, y), duration ms, transparency]
        self.frames = 0

    def _header(self, width: int, height: int) -> None:
        table = bytes(self.palette.getpalette("RGB")[: 3 * 256]).ljust(768, b"\0")
        self.fp.write(b"GIF89a" + struct.pack("<HHBBB", width, height, 0xF7, 0, 0) + table)
        self.fp.write(b"!\xff\x0bNETSCAPE2.0\x03\x01" + struct.pack("<H", 0) + b"\0")

    def add(self, rgba: np.ndarray) -> None:
        """Append the frame ``rgba``, a (height, width, 4) uint8 array (read, not kept)."""
        if rgba.ndim != 3 or rgba.shape[2] != 4 or rgba.dtype != np.uint8:
            raise PlotError(f"a frame must be (height, width, 4) uint8, not {rgba.shape} "
                            f"{rgba.dtype}")
        pixels = np.ascontiguousarray(rgba).view(np.uint32)[:, :, 0]
        height, width = pixels.shape
        if self.previous is None:
            self._header(width, height)
            self.previous = pixels.copy()
            part = _rgb(rgba).quantize(palette=self.palette, dither=Image.Dither.NONE)
            self._flush()
            self.pending = [part, (0, 0), self.duration, None]
            return
        if pixels.shape != self.previous.shape:
            raise PlotError(f"a frame of {width} x {height} pixels after frames of "
                            f"{self.previous.shape[1]} x {self.previous.shape[0]}")
        changed = pixels != self.previous
        rows = np.flatnonzero(changed.any(axis=1))
        if rows.size == 0:
            self.pending[2] += self.duration
            return
        y0, y1 = int(rows[0]), int(rows[-1]) + 1
        cols = np.flatnonzero(changed[y0:y1].any(axis=0))
        x0, x1 = int(cols[0]), int(cols[-1]) + 1
        index = np.asarray(_rgb(rgba[y0:y1, x0:x1]).quantize(palette=self.palette,
                                                             dither=Image.Dither.NONE))
        index = np.where(changed[y0:y1, x0:x1], index, np.uint8(_TRANSPARENT))
        self.previous[y0:y1, x0:x1] = pixels[y0:y1, x0:x1]
        part = Image.fromarray(index, "P")
        part.putpalette(self.palette.getpalette("RGB"))
        self._flush()
        self.pending = [part, (x0, y0), self.duration, _TRANSPARENT]

    def _flush(self) -> None:
        if self.pending is not None:
            part, offset, duration, transparency = self.pending
            info = {"duration": duration, "disposal": 1}
            if transparency is not None:
                info["transparency"] = transparency
            for chunk in GifImagePlugin.getdata(part, offset, **info):
                self.fp.write(chunk)
            self.frames += 1
            self.pending = None

    def close(self) -> int:
        """Write the last frame and the trailer; the number of frames written."""
        if self.previous is None:
            raise PlotError("the animation has no frames")
        self._flush()
        self.fp.write(b";")
        return self.frames


class _Stamp:
    """The time stamp in the top-left corner of the axes, drawn with Pillow onto each frame:
    black monospace text (matplotlib's) on a white box of 80 % opacity. (A matplotlib Text is
    laid out and rasterized anew for every frame, which took about half the GIF's time.)"""

    def __init__(self, ax, fontsize: float = 9.0, anchor=(0.01, 0.99)):
        from matplotlib import font_manager

        dpi = ax.figure.dpi
        path = font_manager.findfont(font_manager.FontProperties(family="monospace"))
        self.font = ImageFont.truetype(path, size=max(round(fontsize * dpi / 72.0), 1))
        self.pad = max(round(0.3 * fontsize * dpi / 72.0), 1)  # matplotlib's bbox padding
        self.ax, self.anchor = ax, anchor
        self.text = ""

    def draw(self, frame: np.ndarray) -> None:
        """Draw the text on ``frame``, the (height, width, 4) RGBA canvas array."""
        if not self.text:
            return
        height, width = frame.shape[:2]
        box = self.ax.get_window_extent()  # pixels, origin at the bottom left
        x = round(box.x0 + self.anchor[0] * box.width)
        y = round(height - (box.y0 + self.anchor[1] * box.height))  # top of the text
        ascent, descent = self.font.getmetrics()
        text_w = math.ceil(self.font.getlength(self.text))
        x0, y0 = max(x - self.pad, 0), max(y - self.pad, 0)
        x1 = min(x + text_w + self.pad, width)
        y1 = min(y + ascent + descent + self.pad, height)
        if x1 <= x0 or y1 <= y0:
            return
        ink = Image.new("L", (x1 - x0, y1 - y0), 0)
        ImageDraw.Draw(ink).text((x - x0, y - y0), self.text, font=self.font, fill=255)
        cover = np.asarray(ink, dtype=np.float32)[:, :, None] / 255.0
        region = frame[y0:y1, x0:x1, :3].astype(np.float32)
        region = (0.2 * region + 0.8 * 255.0) * (1.0 - cover)
        frame[y0:y1, x0:x1, :3] = np.rint(region).astype(np.uint8)


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
        # butt ends: the pieces a trace is drawn in meet without overlapping
        self.robot_trace, = ax.plot([], [], "-", color=C_ROBOT, lw=1.2, label="robot",
                                    solid_capstyle="butt")
        self.last_trace, = ax.plot([], [], "-", color=C_LAST, lw=1.2, solid_capstyle="butt",
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
        self.stamp = _Stamp(ax)

    @property
    def trails(self) -> list:
        """The traces: drawn below the bodies, they only grow."""
        return [self.robot_trace, self.last_trace]

    @property
    def moving(self) -> list:
        """The artists that change from frame to frame, the traces first."""
        return [*self.trails, *self.patches, self.train, self.target]

    def draw(self, frame: int, r: int) -> None:
        """Set the moving artists to frame number ``frame``, which shows data row ``r``."""
        run = self.run
        x, y, th = run.x, run.y, run.th
        self.row = r
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
        self.stamp.text = text

    def grab(self, blit: _Blitter, since: int | None = None) -> np.ndarray:
        """The frame as set by :meth:`draw` (a view of the canvas).

        The traces run from row 0, or, with ``since``, from row ``since``, the row whose frame
        was grabbed last: that part is drawn on the background and kept in it. The bodies,
        the reference point and the stamp go on top.
        """
        run, n, r = self.run, self.run.n, self.row
        first = 0 if since is None else since
        blit.restore()
        self.robot_trace.set_data(run.x[first: r + 1, 0], run.y[first: r + 1, 0])
        self.last_trace.set_data(run.x[first: r + 1, n], run.y[first: r + 1, n])
        blit.draw(self.trails)
        if since is not None:
            blit.keep()
        blit.draw(self.moving[len(self.trails):])
        frame = blit.pixels()
        self.stamp.draw(frame)
        return frame


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
    blit = _Blitter(scene.fig, scene.moving)
    scene.draw(len(frames) - 1, int(frames[-1]))
    last = scene.grab(blit).copy()
    scene.draw(0, int(frames[0]))
    palette = _palette(scene.grab(blit), last, _PALETTE_COLORS)
    del last

    def write(partial: Path) -> None:
        with open(partial, "wb") as f:
            gif = _GifStream(f, palette, 1000.0 / fps)
            since = int(frames[0])
            for frame, r in enumerate(frames):
                scene.draw(frame, int(r))
                gif.add(scene.grab(blit, since))
                since = int(r)
            gif.close()

    atomic(gif_path, write)
    log.debug("wrote %s: %d frames in %.2f s", gif_path, len(frames), _time.perf_counter() - start)
    return gif_path
