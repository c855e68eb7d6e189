"""Between rasters and polygons: regions of a grid traced into shapely polygons (marching
squares), and matplotlib paths of polygons for drawing.

Units: metres. A grid's node (i, j) (row i, column j) sits at (x0 + j h, y0 + i h).
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon

__all__ = ["blocked_polygons", "clear_region", "fill_polygons", "frame_map", "polygon_path"]

_TRACE_LEVEL = 0.49
"""Marching-squares level between free (0) and blocked (1) cell centres: a hair below 1/2, so a
saddle (two blocked cells touching at a corner) is traced as one blocked region, never a gap."""


def _trace(z: np.ndarray, lower: float, upper: float, x0: float, y0: float, h: float,
           tolerance: float):
    """The region where ``z`` (node (i, j) at (x0 + j h, y0 + i h) [m]) lies in [lower, upper],
    traced by marching squares (contourpy, linear between nodes) as a MultiPolygon [m], its
    rings simplified (Douglas-Peucker) by ``tolerance`` [m]."""
    import contourpy

    generator = contourpy.contour_generator(
        z=np.asarray(z, dtype=np.float64), name="serial",
        fill_type=contourpy.FillType.OuterOffset)
    points, offsets = generator.filled(lower, upper)
    polys = []
    for pts, offs in zip(points, offsets, strict=True):
        xy = np.column_stack([x0 + h * pts[:, 0], y0 + h * pts[:, 1]])
        polys.append(Polygon(xy[offs[0]:offs[1]],
                             [xy[offs[k]:offs[k + 1]] for k in range(1, len(offs) - 1)]))
    geom = MultiPolygon(polys)
    if tolerance > 0.0:
        geom = shapely.simplify(geom, tolerance, preserve_topology=False)
    if not geom.is_valid:
        geom = shapely.make_valid(geom)
    parts = [p for g in getattr(geom, "geoms", [geom]) for p in getattr(g, "geoms", [g])
             if isinstance(p, Polygon) and not p.is_empty]
    return MultiPolygon(parts)


def blocked_polygons(grid, tolerance: float | None = None):
    """The blocked cells of ``grid`` as shapely polygons [m] (a MultiPolygon).

    Marching squares at level 0.49 between the cell centres (blocked 1, free 0) traces the
    cells' edges, cutting each corner by at most 0.35 cell; the outside of the grid is blocked.
    The rings are then simplified by ``tolerance`` [m] (default a quarter cell: the trace stays
    0.35 cell from every centre, so centres keep their side, and straight walls lose their
    points).
    """
    h = grid.resolution
    tolerance = 0.25 * h if tolerance is None else float(tolerance)
    z = np.pad(grid.blocked, 1, constant_values=True)
    return _trace(z, _TRACE_LEVEL, 2.0, grid.x0 - h, grid.y0 - h, h, tolerance)


def clear_region(field, margin: float, tolerance: float | None = None):
    """Where a distance field is at least ``margin`` [m]: the free space eroded by ``margin``,
    traced by marching squares on the field's nodes (a MultiPolygon [m]) and simplified by
    ``tolerance`` (default a quarter of the field's resolution)."""
    h = field.resolution
    tolerance = 0.25 * h if tolerance is None else float(tolerance)
    values = field.values
    low = min(float(values.min()), float(margin)) - h
    z = np.pad(values, 1, constant_values=low)
    top = max(float(values.max()), float(margin)) + h
    return _trace(z, float(margin), top, field.x0 - h, field.y0 - h, h, tolerance)



def polygon_path(poly: Polygon):
    """A matplotlib Path of a shapely polygon with its holes (for a PathPatch)."""
    from matplotlib.path import Path as MplPath

    verts, codes = [], []
    for ring in [poly.exterior, *poly.interiors]:
        xy = np.asarray(ring.coords)
        verts += xy.tolist()
        codes += [MplPath.MOVETO] + [MplPath.LINETO] * (len(xy) - 2) + [MplPath.CLOSEPOLY]
    return MplPath(verts, codes)


def fill_polygons(ax, geom, **patch) -> None:
    """Fill every non-empty polygon of ``geom`` (a Polygon, MultiPolygon or collection) on
    ``ax`` with its holes, with the PathPatch settings ``patch``."""
    from matplotlib.patches import PathPatch

    for poly in getattr(geom, "geoms", [geom]):
        if isinstance(poly, Polygon) and not poly.is_empty:
            ax.add_patch(PathPatch(polygon_path(poly), **patch))


def frame_map(ax, bounds, pad: float):
    """Frame ``ax`` on a map's ``bounds`` (xmin, ymin, xmax, ymax) [m] plus ``pad`` [m] on every
    side, at equal scale, with the axes labelled in metres; returns ``ax``."""
    xmin, ymin, xmax, ymax = bounds
    ax.set_xlim(xmin - pad, xmax + pad)
    ax.set_ylim(ymin - pad, ymax + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    return ax
