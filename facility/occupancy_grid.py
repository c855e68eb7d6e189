"""A facility's occupancy grid: the map as its file holds it (:class:`MapImage`, pixels with a
pose) and the axis-aligned grid the planner's distance field is made from
(:class:`OccupancyGrid`), with polygons drawn on top. Reading the ROS ``map_server`` files
that hold them is :mod:`pushtrain.facility.map_server`.

**Pixels and metres.** Image row 0 is the *top* of the map. ``origin`` is the pose of the
lower-left corner of the lower-left pixel (nav_msgs/OccupancyGrid's ``info.origin``), so pixel
(row r, column c) of an H-row image covers the square with corners origin + R(yaw) (u, v),
u in [c h, (c + 1) h], v in [(H - 1 - r) h, (H - r) h].

**Rotated origins.** The planner's distance field is axis-aligned, so a map with yaw != 0 is
resampled once into an axis-aligned grid over its bounding box, at the same resolution, by
nearest neighbour: each new cell takes the pixel under its centre, and a centre outside the image
is blocked. What that costs: the new cells' squares differ from the rotated pixels they copy by up
to half a cell diagonal, so a wall may move by up to h / sqrt(2) (3.5 cm at 5 cm per pixel), on
top of the half cell any grid is uncertain by. The drawings use the original image, rotated.

**Polygons on top.** :meth:`OccupancyGrid.burn` blocks every cell whose centre lies within half a
cell of an obstacle polygon (so a wall thinner than a cell is never lost between two centres), and
every cell whose centre is not half a cell inside a ``keep_in`` outline. The distance field, which
the planner queries, then sees them.

Worlds are made of grids in :mod:`pushtrain.facility.loading`.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import shapely
from shapely.geometry import Polygon, box

from pushtrain.errors import MapError

from .distance_field import MAX_CELLS

__all__ = ["UNKNOWN", "MapImage", "OccupancyGrid"]

log = logging.getLogger(__name__)

UNKNOWN = -1
"""Occupancy value of an unknown cell (map_server's -1)."""

_YAW_TOL = 1e-9
"""|yaw| [rad] below which a map is taken as axis-aligned (no resampling)."""


def _aligned(yaw: float) -> bool:
    """Whether a map of this yaw [rad] is axis-aligned as it is (no resampling)."""
    return abs(math.remainder(yaw, 2.0 * math.pi)) <= _YAW_TOL


# ---------------------------------------------------------------------------------------------
# the map as the file holds it
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class MapImage:
    """An occupancy map as its image holds it (row 0 is the top).

    Attributes
    ----------
    values : (H, W) int16 array
        The map server's occupancy values: 0 free, 100 occupied, -1 unknown, 1..99 in between
        (scale mode); raw mode: the pixel value.
    free : (H, W) bool array
        Known free (p < ``free_thresh``): where bodies may stand.
    resolution : float
        Pixel size h [m].
    origin : (x, y, yaw)
        Pose of the lower-left corner of the lower-left pixel [m, m, rad].
    source : str
        The YAML file it came from (for messages).
    image_file : str
        The image file (for messages).
    """

    values: np.ndarray
    free: np.ndarray
    resolution: float
    origin: tuple
    source: str = ""
    image_file: str = ""

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W): rows, columns."""
        return self.free.shape

    def to_map_frame(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """Map-frame coordinates (u right, v up from the lower-left corner) [m] of world points."""
        ox, oy, yaw = self.origin
        c, s = math.cos(yaw), math.sin(yaw)
        dx = np.asarray(x, dtype=float) - ox
        dy = np.asarray(y, dtype=float) - oy
        return c * dx + s * dy, -s * dx + c * dy

    def pixel_of(self, x, y) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(row, column, inside) of the pixels under world points [m]: row 0 at the top; where
        ``inside`` is False the indices are clipped and meaningless."""
        u, v = self.to_map_frame(x, y)
        h = self.resolution
        height, width = self.shape
        col = np.floor(u / h).astype(np.intp)
        row = height - 1 - np.floor(v / h).astype(np.intp)
        inside = (col >= 0) & (col < width) & (row >= 0) & (row < height)
        return np.clip(row, 0, height - 1), np.clip(col, 0, width - 1), inside

    def corners(self) -> np.ndarray:
        """World corners [m] of the image, (4, 2): lower-left, lower-right, upper-right,
        upper-left."""
        ox, oy, yaw = self.origin
        height, width = self.shape
        h = self.resolution
        uv = np.array([[0.0, 0.0], [width * h, 0.0], [width * h, height * h], [0.0, height * h]])
        c, s = math.cos(yaw), math.sin(yaw)
        return np.column_stack([ox + c * uv[:, 0] - s * uv[:, 1], oy + s * uv[:, 0] + c * uv[:, 1]])

    def footprint(self) -> Polygon:
        """The image's area in the world (a rectangle, rotated by yaw) [m]."""
        return Polygon(self.corners())

    def shade(self) -> np.ndarray:
        """Grey levels (H, W) in [0, 1] to draw: free light, occupied dark, unknown mid grey,
        in-between values graded."""
        v = self.values.astype(float)
        known = (v >= 0) & (v <= 100)
        out = np.where(known, 0.96 - 0.71 * np.clip(v, 0, 100) / 100.0, 0.72)
        return np.where(self.free, 0.96, np.where(known & (v <= 0), 0.72, out))

    def plot(self, ax, zorder: float = 0.0, max_pixels: int = 1600):
        """Draw the image on ``ax`` in world coordinates (origin, resolution and yaw applied).

        An image wider or taller than ``max_pixels`` is drawn reduced by a whole factor, each
        drawn pixel the darkest of those it stands for (a wall one pixel thin stays visible,
        and every frame of an animation does not resample millions of pixels)."""
        from matplotlib.transforms import Affine2D

        height, width = self.shape
        h = self.resolution
        ox, oy, yaw = self.origin
        shade = self.shade()
        k = max(1, math.ceil(max(height, width) / max_pixels))
        if k > 1:
            padded = np.pad(shade, ((0, -height % k), (0, -width % k)), mode="edge")
            shade = padded.reshape(padded.shape[0] // k, k, padded.shape[1] // k, k).min(
                axis=(1, 3))
        rows, cols = shade.shape
        image = ax.imshow(shade, cmap="gray", vmin=0.0, vmax=1.0, origin="upper",
                          extent=(0.0, cols * k * h, (height - rows * k) * h, height * h),
                          interpolation="antialiased", zorder=zorder)
        image.set_transform(Affine2D().rotate(yaw).translate(ox, oy) + ax.transData)
        return image


# ---------------------------------------------------------------------------------------------
# the axis-aligned grid the planner uses
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class OccupancyGrid:
    """An axis-aligned occupancy grid: what :attr:`World.occupancy
    <pushtrain.facility.free_space.World.occupancy>` and the distance field take.

    Attributes
    ----------
    blocked : (ny, nx) bool array
        Cells bodies must not touch; row i is at ``y0 + i h`` (row 0 lowest).
    x0, y0 : float
        Centre of cell (0, 0) [m].
    resolution : float
        Cell size h [m].
    image : MapImage or None
        The map file this grid was made from (drawn by :meth:`plot`).
    extra : tuple of shapely Polygon
        Polygons burned in by :meth:`burn` (drawn on top of the image).
    keep_in : shapely Polygon or None
        Outline burned in by :meth:`burn` (everything outside it is blocked).
    """

    blocked: np.ndarray
    x0: float
    y0: float
    resolution: float
    image: MapImage | None = None
    extra: tuple = ()
    keep_in: Polygon | None = None

    def __post_init__(self):
        blocked = np.ascontiguousarray(self.blocked, dtype=bool)
        if blocked.ndim != 2 or min(blocked.shape) < 2:
            raise MapError(self._source(), [("image", f"{blocked.shape[::-1]} pixels",
                                             "at least 2 x 2 pixels")])
        object.__setattr__(self, "blocked", blocked)
        blocked.setflags(write=False)

    def _source(self) -> str:
        return self.image.source if self.image is not None else "<grid>"

    @classmethod
    def from_image(cls, image: MapImage) -> OccupancyGrid:
        """The axis-aligned grid of ``image`` (resampled by nearest neighbour if it is rotated,
        see the module docstring)."""
        h = image.resolution
        ox, oy, yaw = image.origin
        if _aligned(yaw):
            return cls(~image.free[::-1], ox + 0.5 * h, oy + 0.5 * h, h, image)
        corners = image.corners()
        (xmin, ymin), (xmax, ymax) = corners.min(axis=0), corners.max(axis=0)
        nx = max(int(math.ceil((xmax - xmin) / h - 1e-9)), 2)
        ny = max(int(math.ceil((ymax - ymin) / h - 1e-9)), 2)
        if nx * ny > MAX_CELLS:
            raise MapError(image.source, [("origin", list(image.origin),
                                           f"rotated, the map needs {nx} x {ny} cells: at most "
                                           f"{MAX_CELLS}")])
        x0, y0 = xmin + 0.5 * h, ymin + 0.5 * h
        xs = x0 + h * np.arange(nx)
        ys = y0 + h * np.arange(ny)
        row, col, inside = image.pixel_of(xs[None, :], ys[:, None])
        blocked = ~(image.free[row, col] & inside)
        return cls(blocked, x0, y0, h, image)

    # ------------------------------------------------------------------ geometry
    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx)."""
        return self.blocked.shape

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) [m] of the cells' outer edges."""
        ny, nx = self.blocked.shape
        h = self.resolution
        return (self.x0 - 0.5 * h, self.y0 - 0.5 * h, self.x0 + (nx - 0.5) * h,
                self.y0 + (ny - 0.5) * h)

    def footprint(self) -> Polygon:
        """The area the map covers [m]: the image (rotated) if known, else the grid's box, cut
        to ``keep_in``."""
        area = self.image.footprint() if self.image is not None else box(*self.bounds)
        if self.keep_in is not None:
            area = area.intersection(self.keep_in)
        return area

    def centres(self, i0: int = 0, i1: int | None = None, j0: int = 0, j1: int | None = None):
        """Cell-centre coordinates [m] of rows i0..i1-1 and columns j0..j1-1 (broadcastable)."""
        ny, nx = self.blocked.shape
        i1 = ny if i1 is None else i1
        j1 = nx if j1 is None else j1
        h = self.resolution
        xs = self.x0 + h * np.arange(j0, j1)
        ys = self.y0 + h * np.arange(i0, i1)
        return xs[None, :], ys[:, None]

    def cell_of(self, x: float, y: float) -> tuple[int, int] | None:
        """(row, column) of the cell containing (x, y) [m], or None outside the grid."""
        h = self.resolution
        j = math.floor((x - self.x0) / h + 0.5)
        i = math.floor((y - self.y0) / h + 0.5)
        ny, nx = self.blocked.shape
        return (i, j) if 0 <= i < ny and 0 <= j < nx else None

    def why_blocked(self, x: float, y: float) -> str | None:
        """None if (x, y) [m] lies on a free cell, else what is there, naming the image pixel."""
        cell = self.cell_of(x, y)
        if cell is not None and not self.blocked[cell]:
            return None
        where = f"({x:g}, {y:g}) m"
        img = self.image
        if img is None:
            return (f"{where} is outside the map" if cell is None else
                    f"{where} is on a blocked cell (row {cell[0]}, column {cell[1]})")
        name = Path(img.image_file or img.source).name or "the map"
        if _aligned(img.origin[2]) and cell is not None:  # the grid is the image, flipped
            row, col, inside = img.shape[0] - 1 - cell[0], cell[1], True
        else:
            row, col, inside = (int(a) for a in img.pixel_of(x, y))
        if not inside:
            corners = np.round(img.corners(), 3).tolist()
            return f"{where} is outside the map image of {name} (its corners are at {corners} m)"
        if not img.free[row, col]:
            value = int(img.values[row, col])
            state = {100: "occupied", UNKNOWN: "unknown"}.get(value, f"not free ({value})")
            return (f"{where} is on a pixel of {name} that is {state} (row {row}, column {col}; "
                    "row 0 is the top of the image)")
        return (f"{where} is on a blocked cell: inside a polygon drawn on the map, outside its "
                "free outline, or (a rotated map) next to a blocked pixel")

    # ------------------------------------------------------------------ polygons on top
    def burn(self, obstacles=(), keep_in: Polygon | None = None) -> OccupancyGrid:
        """A copy with ``obstacles`` (shapely polygons [m]) blocked and, with ``keep_in``,
        everything outside that outline blocked (cell rule in the module docstring)."""
        obstacles = tuple(g for g in obstacles if not g.is_empty)
        if not obstacles and keep_in is None:
            return self
        blocked = np.array(self.blocked)
        h = self.resolution
        for poly in obstacles:
            grown = poly.buffer(0.5 * h)
            window = self._window(grown.bounds)
            if window is None:
                continue
            i0, i1, j0, j1 = window
            xs, ys = self.centres(i0, i1, j0, j1)
            blocked[i0:i1, j0:j1] |= shapely.contains_xy(grown, xs, ys)
        if keep_in is not None:
            inner = keep_in.buffer(-0.5 * h)
            inside = np.zeros_like(blocked)
            window = None if inner.is_empty else self._window(inner.bounds)
            if window is not None:
                i0, i1, j0, j1 = window
                xs, ys = self.centres(i0, i1, j0, j1)
                inside[i0:i1, j0:j1] = shapely.contains_xy(inner, xs, ys)
            blocked |= ~inside
            keep_in = keep_in if self.keep_in is None else self.keep_in.intersection(keep_in)
        else:
            keep_in = self.keep_in
        return replace(self, blocked=blocked, extra=self.extra + obstacles, keep_in=keep_in)

    def _window(self, bounds) -> tuple[int, int, int, int] | None:
        """Row and column ranges [i0, i1) x [j0, j1) of the cells whose centres may lie in
        ``bounds`` (xmin, ymin, xmax, ymax) [m]; None if none."""
        xmin, ymin, xmax, ymax = bounds
        h = self.resolution
        ny, nx = self.blocked.shape
        j0 = max(int(math.floor((xmin - self.x0) / h)), 0)
        j1 = min(int(math.ceil((xmax - self.x0) / h)) + 1, nx)
        i0 = max(int(math.floor((ymin - self.y0) / h)), 0)
        i1 = min(int(math.ceil((ymax - self.y0) / h)) + 1, ny)
        return (i0, i1, j0, j1) if i1 > i0 and j1 > j0 else None

    # ------------------------------------------------------------------ drawing
    def plot(self, ax, obstacle_color: str = "#606060"):
        """Draw the map image (rotated as it lies) and the polygons burned on top."""
        from .raster import fill_polygons, frame_map

        if self.image is not None:
            self.image.plot(ax)
        else:
            xmin, ymin, xmax, ymax = self.bounds
            ax.imshow(np.where(self.blocked, 0.25, 0.96), cmap="gray", vmin=0.0, vmax=1.0,
                      origin="lower", extent=(xmin, xmax, ymin, ymax), zorder=0)
        drawn = list(self.extra)
        if self.keep_in is not None:
            drawn.append(self.footprint().envelope.buffer(self.resolution).difference(self.keep_in))
        for geom in drawn:
            fill_polygons(ax, geom, facecolor=obstacle_color, edgecolor="none", alpha=0.9,
                          zorder=0.5)
        xmin, ymin, xmax, ymax = bounds = self.footprint().bounds
        return frame_map(ax, bounds, 0.02 * max(xmax - xmin, ymax - ymin, 1e-9))
