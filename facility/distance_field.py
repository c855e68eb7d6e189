"""Signed distance to the nearest blocked point, sampled on a regular grid: the planner's fast
collision query.

A body keeps ``margin`` metres from every wall exactly when every point of its footprint has a
signed distance of at least ``margin``. The planner samples each footprint at a few points and
looks their distance up here (bilinear interpolation, vectorized, or in C from the raw array), so
a collision query costs the same on a typed-in polygon map and on a 2000 x 2000 occupancy grid.

Two sources, one layout:

Polygon maps (:meth:`DistanceField.from_world`)
    The free space is rasterized at the grid nodes (``shapely.contains_xy``); the distance from a
    node to the blocked region comes first from the Euclidean distance transform of that raster
    (:func:`scipy.ndimage.distance_transform_edt`, error below one cell), and is then replaced by
    the *exact* distance to the free space's boundary segments for every node within ``band`` of a
    wall. Near the walls, where the answer matters, the node values are exact; between nodes the
    bilinear interpolation of a distance (a 1-Lipschitz function) errs by at most ``h / sqrt(2)``,
    and not at all along a straight wall.
Occupancy grids (:meth:`DistanceField.from_occupancy`)
    The grid's own cells are the nodes: a free cell's value is the distance from its centre to the
    nearest blocked cell's centre minus half a cell (the wall lies between them), a blocked cell's
    the negative of the same towards the free cells. Exact to the grid's resolution, which is all
    an occupancy grid knows.

Everything outside the grid counts as blocked (the lookup returns ``-inf`` there).

Units: metres. Node (i, j) (row i, column j) sits at ``(x0 + j h, y0 + i h)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely

from pushtrain.core.field import values_at
from pushtrain.errors import PlanningInputError

__all__ = ["DistanceField", "DEFAULT_RESOLUTION", "MAX_CELLS"]

DEFAULT_RESOLUTION = 0.02
"""Node spacing [m] for polygon maps: 2 cm, below the centimetre margins of a docking bay once the
exact near-wall values are used."""

MAX_CELLS = 25_000_000
"""Largest grid accepted (200 MB of float64): 100 m x 100 m at 2 cm, or 5000 x 5000 cells."""


@dataclass(frozen=True, eq=False)
class DistanceField:
    """Signed distance [m] to the blocked region on a grid: > 0 free, < 0 blocked.

    Attributes
    ----------
    values : (ny, nx) float64 array, C-contiguous
        Signed distance at the nodes [m].
    x0, y0 : float
        Position of node (0, 0) [m].
    resolution : float
        Node spacing h [m], > 0.
    """

    values: np.ndarray
    x0: float
    y0: float
    resolution: float

    def __post_init__(self):
        values = np.ascontiguousarray(self.values, dtype=float)
        if values.ndim != 2 or min(values.shape) < 2:
            raise PlanningInputError(
                f"distance field values have shape {values.shape}: need at least 2 x 2 nodes")
        if not (math.isfinite(self.resolution) and self.resolution > 0.0):
            raise PlanningInputError(
                f"distance field resolution = {self.resolution!r} m: must be finite and > 0")
        object.__setattr__(self, "values", values)
        for name in ("x0", "y0", "resolution"):
            object.__setattr__(self, name, float(getattr(self, name)))
        values.setflags(write=False)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_occupancy(cls, blocked, x0: float, y0: float, resolution: float) -> DistanceField:
        """The field of an occupancy grid: ``blocked`` (ny, nx) bool, row i at ``y0 + i h``.

        Cell centres are the nodes (``x0, y0`` is the centre of cell (0, 0)). A grid without any
        blocked cell is bounded by its own edge (the world ends there).
        """
        blocked = np.asarray(blocked, dtype=bool)
        if blocked.ndim != 2:
            raise PlanningInputError(f"occupancy grid has shape {blocked.shape}: need 2-D")
        if blocked.size > MAX_CELLS:
            raise PlanningInputError(
                f"occupancy grid has {blocked.size} cells: at most {MAX_CELLS} are supported")
        from scipy import ndimage  # imported here: 0.35 s that runs without a field never pay

        h = float(resolution)
        # one blocked cell of border: outside the grid is unknown, and unknown counts as blocked
        padded = np.pad(blocked, 1, constant_values=True)
        free_side = ndimage.distance_transform_edt(~padded)
        blocked_side = ndimage.distance_transform_edt(padded)
        signed = np.where(padded, -(blocked_side - 0.5), free_side - 0.5) * h
        return cls(signed[1:-1, 1:-1], float(x0), float(y0), h)

    @classmethod
    def from_world(cls, world, resolution: float = DEFAULT_RESOLUTION,
                   band: float = 1.0) -> DistanceField:
        """The field of a polygon :class:`~pushtrain.facility.free_space.World` (exact within
        ``band`` [m] of a wall, see the module docstring); the grid covers the outline plus two
        cells."""
        h = float(resolution)
        if not (math.isfinite(h) and h > 0.0):
            raise PlanningInputError(f"resolution = {resolution!r} m: must be finite and > 0")
        xmin, ymin, xmax, ymax = world.outline.bounds
        pad = 2.0 * h
        nx = int(math.ceil((xmax - xmin + 2 * pad) / h)) + 1
        ny = int(math.ceil((ymax - ymin + 2 * pad) / h)) + 1
        if nx * ny > MAX_CELLS:
            raise PlanningInputError(
                f"a {xmax - xmin:.1f} m x {ymax - ymin:.1f} m map at resolution {h} m needs "
                f"{nx * ny} grid nodes: at most {MAX_CELLS}; use a coarser resolution")
        from scipy import ndimage

        x0, y0 = xmin - pad, ymin - pad
        xs = x0 + h * np.arange(nx)
        ys = y0 + h * np.arange(ny)
        free = shapely.contains_xy(world.free, xs[None, :], ys[:, None])
        blocked = ~free
        signed = np.where(blocked, -(ndimage.distance_transform_edt(blocked) - 0.5),
                          ndimage.distance_transform_edt(free) - 0.5) * h
        exact = _segment_distances(_boundary_segments(world.free), x0, y0, h, ny, nx, band)
        near = np.isfinite(exact)
        signed[near] = np.where(blocked[near], -exact[near], exact[near])
        return cls(signed, x0, y0, h)

    # ------------------------------------------------------------------ queries
    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx)."""
        return self.values.shape

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of the nodes [m]."""
        ny, nx = self.values.shape
        h = self.resolution
        return (self.x0, self.y0, self.x0 + (nx - 1) * h, self.y0 + (ny - 1) * h)

    def at(self, x, y) -> np.ndarray:
        """Signed distance [m] at points (arrays of any shapes that broadcast together, or
        scalars), bilinear between nodes; ``-inf`` outside the grid (and at NaN).

        One pass in C over the points (:func:`pushtrain.core.field.values_at`): the node below a
        point is the cell's corner (the last cell's at the grid's far edges), its weights lie in
        [0, 1]; the arithmetic is the bilinear formula operation for operation, without fused
        multiply-add (checked bit for bit against ``tests/reference/field_lookup.py``, the same
        formula in Python a point at a time)."""
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        if x.shape != y.shape:
            x, y = np.broadcast_arrays(x, y)
        if not x.flags.c_contiguous:  # (np.ascontiguousarray would make a 0-d array 1-d)
            x = x.copy()
        if not y.flags.c_contiguous:
            y = y.copy()
        return values_at(self.values, self.x0, self.y0, self.resolution, x, y)

    def clear(self, x, y, margin) -> np.ndarray:
        """Whether each point keeps ``margin`` [m] (scalar or broadcastable) from every wall."""
        return self.at(x, y) >= margin


def _boundary_segments(geom) -> np.ndarray:
    """Every edge of every ring of a (multi)polygon as an (m, 4) array (xa, ya, xb, yb)."""
    rings = []
    for poly in getattr(geom, "geoms", [geom]):
        if poly.is_empty:
            continue
        for ring in [poly.exterior, *poly.interiors]:
            xy = np.asarray(ring.coords, dtype=float)
            rings.append(np.hstack([xy[:-1], xy[1:]]))
    return np.vstack(rings) if rings else np.zeros((0, 4))


def _segment_distances(segments: np.ndarray, x0: float, y0: float, h: float, ny: int, nx: int,
                       band: float) -> np.ndarray:
    """Exact distance [m] from each node to the nearest segment, for nodes within ``band`` of one
    (``inf`` elsewhere): each segment is measured only in its own bounding box grown by ``band``."""
    out = np.full((ny, nx), np.inf)
    for xa, ya, xb, yb in segments:
        j0 = max(int(math.floor((min(xa, xb) - band - x0) / h)), 0)
        j1 = min(int(math.ceil((max(xa, xb) + band - x0) / h)), nx - 1)
        i0 = max(int(math.floor((min(ya, yb) - band - y0) / h)), 0)
        i1 = min(int(math.ceil((max(ya, yb) + band - y0) / h)), ny - 1)
        if j1 < j0 or i1 < i0:
            continue
        px = (x0 + h * np.arange(j0, j1 + 1))[None, :] - xa
        py = (y0 + h * np.arange(i0, i1 + 1))[:, None] - ya
        dx, dy = xb - xa, yb - ya
        length2 = dx * dx + dy * dy
        t = np.clip((px * dx + py * dy) / length2, 0.0, 1.0) if length2 > 0.0 else 0.0
        d = np.hypot(px - t * dx, py - t * dy)
        window = out[i0:i1 + 1, j0:j1 + 1]
        np.minimum(window, d, out=window)
    out[out > band] = np.inf
    return out
