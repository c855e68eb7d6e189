"""A facility's free space: the :class:`World` the train moves in.

A :class:`World` is free space in the plane: the inside of an optional outline polygon
(``free``) minus any number of obstacle polygons (``obstacles`` and ``walls`` are synonyms), or
the free cells of an occupancy grid (:mod:`pushtrain.facility.loading`). Everything is plain data
(lists of ``[x, y]`` points, metres) so a scenario file can hold it. The train's bodies are the
planner's (:mod:`pushtrain.planner.train`).
"""

from __future__ import annotations

import logging
import re
import threading
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Point, Polygon, box
from shapely.ops import nearest_points, unary_union
from shapely.validation import explain_validity

from pushtrain.errors import PlanningInputError

from .distance_field import DEFAULT_RESOLUTION, DistanceField
from .raster import fill_polygons, frame_map

__all__ = ["World", "outline_problem", "polygon_from_points"]

log = logging.getLogger(__name__)

_WORLD_KEYS = ("free", "obstacles", "walls", "bounds")


def outline_problem(poly: Polygon) -> str | None:
    """None if ``poly`` is a simple polygon, else what is wrong and where, e.g. ``"not a simple
    polygon (self-intersection at (7, 0) m): the outline of the free space must not cross or
    touch itself"`` (shapely's ``explain_validity``)."""
    if poly.is_valid:
        return None
    reason = explain_validity(poly)  # e.g. "Self-intersection[7 0]"
    place = re.fullmatch(r"(.*)\[(\S+) (\S+)\]", reason)
    if place:
        reason = f"{place[1].lower()} at ({float(place[2]):g}, {float(place[3]):g}) m"
    return (f"not a simple polygon ({reason}): the outline of the free space must not cross or "
            "touch itself")


def polygon_from_points(points: Any, field_name: str, outline: bool = False) -> Polygon:
    """A valid shapely polygon from a list of [x, y] points [m]; PlanningInputError otherwise.

    A polygon that crosses or touches itself is an error if it is the free space's ``outline``
    (the message says where, by :func:`outline_problem`, also in the error's
    ``details["outline_problem"]``); an obstacle is repaired with ``make_valid`` (the areas it
    encloses) and a warning."""
    try:
        arr = np.asarray(points, dtype=float)
    except (TypeError, ValueError) as exc:
        raise PlanningInputError(
            f"{field_name} = {points!r}: need a list of [x, y] points (numbers)"
        ) from exc
    if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] < 3:
        raise PlanningInputError(
            f"{field_name} has shape {arr.shape}: need at least 3 points [x, y]"
        )
    if not np.all(np.isfinite(arr)):
        raise PlanningInputError(f"{field_name} contains non-finite coordinates")
    poly = Polygon(arr)
    if outline and (why := outline_problem(poly)) is not None:
        raise PlanningInputError(f"{field_name} is {why}", details={"outline_problem": why})
    if not poly.is_valid:
        fixed = shapely.make_valid(poly)
        polys = [
            g for g in getattr(fixed, "geoms", [fixed]) if isinstance(g, (Polygon, MultiPolygon))
        ]
        poly = unary_union(polys) if polys else Polygon()
        log.warning("%s was not a valid (simple) polygon (%s); repaired with make_valid",
                    field_name, explain_validity(Polygon(arr)))
    return poly


def _boundary_pieces(free, points: int = 16) -> np.ndarray:
    """The rings of ``free`` cut into line strings of ``points`` edges (the last of a ring
    shorter), in ring order, each sharing its end point with the next: one array of shapely
    line strings, made at once (a SLAM map has thousands of rings)."""
    rings = shapely.get_parts(shapely.get_rings(shapely.get_parts(free)))
    xy, ring = shapely.get_coordinates(rings, return_index=True)
    if not xy.size:
        return np.array([], dtype=object)
    first = np.flatnonzero(np.r_[True, ring[1:] != ring[:-1]])  # each ring's first point
    size = np.diff(np.r_[first, ring.size])
    at = np.arange(ring.size) - np.repeat(first, size)  # place of each point in its ring
    edges = np.repeat(size - 1, size)
    count = (size - 1 + points - 1) // points  # pieces of each ring
    base = np.repeat(np.cumsum(count) - count, size)  # the ring's first piece
    # a point p starts or continues piece p // points (the ring's last point closes its last
    # piece); one at a multiple of ``points`` also ends the piece before
    own = at < edges
    own_piece = base + np.minimum(at // points, np.repeat(count, size) - 1)
    ends = (at % points == 0) & (at > 0) & own
    piece = np.concatenate([own_piece[own | (at == edges)], (base + at // points - 1)[ends]])
    order_in = np.concatenate([at[own | (at == edges)], at[ends]])
    coords = np.concatenate([xy[own | (at == edges)], xy[ends]])
    order = np.lexsort((order_in, piece))
    return shapely.linestrings(coords[order], indices=piece[order])


@dataclass(frozen=True, eq=False)
class World:
    """Free space for the train: ``outline`` minus ``obstacles``.

    Parameters
    ----------
    outline : shapely Polygon
        Region the bodies must stay inside [m].
    obstacles : tuple of shapely Polygon
        Regions the bodies must not touch [m] (walls, shelves, ...).

    Use :meth:`from_dict` to build one from plain data.
    """

    outline: Polygon
    obstacles: tuple = ()
    occupancy: Any = None
    """Optional raster source of the map (an occupancy grid with ``blocked`` (ny, nx) bool,
    ``x0``, ``y0`` (centre of cell (0, 0), m) and ``resolution`` (m), axis-aligned): when set,
    :meth:`distance_field` comes from it instead of rasterizing the polygons."""
    free: Any = field(default=None, repr=False)
    """The free space: ``outline`` minus ``obstacles``, computed unless given (a caller that has
    it cheaper, e.g. a traced occupancy grid whose thousands of disjoint pieces need no union)."""
    labels: tuple = field(default=(), repr=False)
    """What each obstacle is, for messages (``"map.obstacles[2]"``, ``"the closed LWPOLYLINE
    (handle 2F) on layer WALLS of floor.dxf"``), in the order of ``obstacles``; may be shorter."""
    outline_label: str = field(default="", repr=False)
    """What the outline is, for messages (``"map.free"``, ``"the drawing's extent"``)."""
    cache_key: str | None = field(default=None, repr=False)
    """The map cache's key of :attr:`occupancy` (:func:`~pushtrain.facility.map_cache.map_key`)
    when the map came through the cache: :meth:`eroded` keeps its regions there too."""
    _fields: dict = field(init=False, repr=False, default_factory=dict)

    def __post_init__(self):
        free = self.free
        if free is None:
            free = self.outline
            if self.obstacles:
                free = free.difference(unary_union(list(self.obstacles)))
            object.__setattr__(self, "free", free)
        shapely.prepare(free)

    def distance_field(self, resolution: float | None = None) -> DistanceField:
        """The signed distance field of this map (cached per resolution): from :attr:`occupancy`
        at its own resolution if set, else from the polygons at ``resolution`` [m] (default
        :data:`~pushtrain.facility.distance_field.DEFAULT_RESOLUTION`)."""
        key = None if self.occupancy is not None else (resolution or DEFAULT_RESOLUTION)
        cached = self._fields.get(key)
        if cached is None:
            if self.occupancy is not None:
                grid = self.occupancy
                cached = DistanceField.from_occupancy(grid.blocked, grid.x0, grid.y0,
                                                      grid.resolution)
            else:
                cached = DistanceField.from_world(self, key)
            self._fields[key] = cached
        return cached

    def adopt_distance_field(self, field: DistanceField) -> None:
        """Use ``field`` as the distance field of this grid world (one computed before from
        the same :attr:`occupancy`, e.g. read from :mod:`~pushtrain.facility.map_cache`)."""
        grid = self.occupancy
        if grid is None or field.shape != grid.blocked.shape:
            raise ValueError("adopt_distance_field: the field is not this grid world's")
        self._fields[None] = field

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "World":
        """Build a world from a scenario file's ``[world]`` section (plain data, metres).

        Accepted keys:

        ``free``
            ``[[x, y], ...]``: outline of the free space (a simple polygon, either orientation;
            one that crosses or touches itself is repaired by ``make_valid``, with a warning:
            two rooms touching along a wall become two parts. A scenario's ``map.free`` is
            refused instead, by :func:`~pushtrain.facility.loading.map_world`).
        ``obstacles``, ``walls``
            ``[[[x, y], ...], ...]``: polygons removed from the free space (synonyms; both may
            be given, they are combined).
        ``bounds``
            ``[xmin, ymin, xmax, ymax]``: a rectangular outline, used when ``free`` is absent.

        At least one of ``free`` and ``bounds`` is required. Unknown keys are an error.
        """
        if not isinstance(data, Mapping):
            raise PlanningInputError(f"world must be a table/dict, got {type(data).__name__}")
        unknown = sorted(set(data) - set(_WORLD_KEYS))
        if unknown:
            raise PlanningInputError(f"world has unknown keys {unknown}: allowed are {_WORLD_KEYS}")
        if "free" in data:
            outline = polygon_from_points(data["free"], "world.free")
        elif "bounds" in data:
            b = np.asarray(data["bounds"], dtype=float).reshape(-1)
            if b.size != 4 or not np.all(np.isfinite(b)) or b[2] <= b[0] or b[3] <= b[1]:
                raise PlanningInputError(
                    f"world.bounds = {data['bounds']!r}: need [xmin, ymin, xmax, ymax] with "
                    "xmax > xmin and ymax > ymin"
                )
            outline = box(*b)
        else:
            raise PlanningInputError("world needs 'free' (an outline) or 'bounds'")
        obstacles = []
        for key in ("obstacles", "walls"):
            items = data.get(key, [])
            if not isinstance(items, Sequence):
                raise PlanningInputError(f"world.{key} must be a list of polygons")
            obstacles += [polygon_from_points(p, f"world.{key}[{k}]") for k, p in enumerate(items)]
        return cls(outline, tuple(obstacles))

    def to_dict(self) -> dict:
        """Plain-data form accepted by :meth:`from_dict` (outline and obstacle exteriors)."""

        def rings(geom):
            polys = geom.geoms if isinstance(geom, MultiPolygon) else [geom]
            return [np.asarray(p.exterior.coords)[:-1].tolist() for p in polys if not p.is_empty]

        out = {"free": rings(self.outline)[0]} if not self.outline.is_empty else {"free": []}
        holes = [np.asarray(r.coords)[:-1].tolist() for r in getattr(self.outline, "interiors", [])]
        obstacles = holes + [r for o in self.obstacles for r in rings(o)]
        if obstacles:
            out["obstacles"] = obstacles
        return out

    # ------------------------------------------------------------------ queries
    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of the free space [m]; the outline's if it is empty."""
        geom = self.outline if self.free.is_empty else self.free
        return tuple(float(a) for a in geom.bounds)

    @property
    def free_area(self) -> float:
        """Area of the free space [m²]."""
        return float(self.free.area)

    def wall_distance(self, geoms, max_distance: float | None = None) -> np.ndarray:
        """Distance [m] from each of ``geoms`` (shapely geometries, any array shape) to the
        free space's boundary (the walls), as ``shapely.distance(free.boundary, geoms)`` but
        through an STRtree of the boundary cut into short pieces, built once: a SLAM map's
        boundary has thousands of rings, and GEOS measures a plain multi-line against every
        one of them (seconds for a path's footprints on an office floor). With
        ``max_distance`` [m], a geometry farther than that from every wall gets ``inf`` (the
        tree's search stops there: much faster for bodies in open space)."""
        geoms = np.asarray(geoms, dtype=object)
        tree = self._fields.get("wall_tree")
        if tree is None:
            pieces = _boundary_pieces(self.free)
            tree = shapely.STRtree(pieces) if pieces.size else None
            self._fields["wall_tree"] = tree
        out = np.full(geoms.shape, np.inf)
        if tree is None or not geoms.size:
            return out
        flat = geoms.reshape(-1)
        (index, _), dist = tree.query_nearest(flat, max_distance=max_distance,
                                              return_distance=True, all_matches=False)
        result = np.full(flat.size, np.inf)
        np.minimum.at(result, index, dist)
        out.reshape(-1)[:] = result
        return out

    def eroded(self, margin: float):
        """Free space shrunk by ``margin`` [m] (prepared): a body inside it keeps that clearance.
        With an occupancy grid: where its distance field is at least ``margin``, traced
        (:func:`pushtrain.facility.raster.clear_region`; exact to the grid's resolution, like the
        field), within the free space.

        Computed once per margin; each thread gets its own prepared copy (GEOS builds a prepared
        geometry's index lazily, so one must not be shared between threads: two threads
        querying one ``free`` crashed the interpreter now and then). A margin of 0 or less is
        the free space itself, in this thread's copy."""
        margin = max(float(margin), 0.0)
        own = ("eroded", margin, threading.get_ident())
        geom = self._fields.get(own)
        if geom is None:
            shared = self._fields.get(("eroded", margin))
            if shared is None and margin == 0.0:
                shared = self.free
            elif shared is None:
                if self.occupancy is not None:
                    shared = self._eroded_grid(margin)
                else:
                    shared = self.free.buffer(-margin, quad_segs=16)
                self._fields[("eroded", margin)] = shared
            geom = shapely.from_wkb(shapely.to_wkb(shared))
            shapely.prepare(geom)
            self._fields[own] = geom
        return geom

    def _eroded_grid(self, margin: float):
        """The grid world's free space shrunk by ``margin`` > 0 [m] (see :meth:`eroded`): from
        the map cache when the map came through it (0.1-0.2 s on an office floor, read back in
        milliseconds), else traced."""
        from .raster import clear_region

        def build():
            return clear_region(self.distance_field(), margin).intersection(self.free)

        if self.cache_key is None:
            return build()
        from .map_cache import eroded

        return eroded(self.cache_key, margin, build)

    def with_obstacles(self, extra: Sequence[Polygon]) -> "World":
        """A copy with ``extra`` obstacle polygons added. An occupancy grid that can burn
        polygons in (:meth:`pushtrain.facility.occupancy_grid.OccupancyGrid.burn`) gets them burned
        in; any other is dropped, and the copy's distance field comes from its polygons."""
        grid = self.occupancy
        if grid is None or not hasattr(grid, "burn"):
            return World(self.outline, tuple(self.obstacles) + tuple(extra),
                         labels=self.labels, outline_label=self.outline_label)
        free = self.free.difference(unary_union(list(extra))) if extra else self.free
        return World(self.outline, tuple(self.obstacles) + tuple(extra),
                     occupancy=grid.burn(tuple(extra)), free=free, labels=self.labels,
                     outline_label=self.outline_label)

    def contains_point(self, x: float, y: float) -> bool:
        """Whether (x, y) [m] lies in the free space."""
        return bool(self.free.contains(Point(float(x), float(y))))

    def why_not_free(self, x: float, y: float) -> str | None:
        """None if (x, y) [m] lies in the free space, else why not: outside the outline, or
        inside an obstacle, named by :attr:`labels` (the first that holds the point)."""
        point = Point(float(x), float(y))
        if self.free.contains(point):
            return None
        where = f"({x:g}, {y:g}) m"
        if not self.outline.contains(point):
            label = self.outline_label or "the outline"
            xmin, ymin, xmax, ymax = self.outline.bounds
            if not (xmin <= x <= xmax and ymin <= y <= ymax) or self.free.is_empty:
                return (f"{where} lies outside {label} (x from {xmin:g} to {xmax:g} m, y from "
                        f"{ymin:g} to {ymax:g} m)")
            # within the outline's bounds but not on it (an L, a ring): where the free space is
            near = nearest_points(self.free, point)[0]
            return (f"{where} lies outside {label}, within its bounds but off its polygon: the "
                    f"nearest free point is ({near.x:.2f}, {near.y:.2f}) m, "
                    f"{point.distance(near):.2f} m away")
        for k, obstacle in enumerate(self.obstacles):
            if obstacle.intersects(point):
                label = self.labels[k] if k < len(self.labels) else f"obstacle {k}"
                return f"{where} lies inside {label}"
        return f"{where} lies on the edge of the free space"

    # ------------------------------------------------------------------ drawing
    def plot(self, ax, free_color: str = "#f4f4f4", obstacle_color: str = "#606060"):
        """Draw the map on ``ax``: the occupancy grid's own picture (its image, rotated as it
        lies, and the polygons drawn on top) if it has one, else the free space (light) and
        everything else inside the bounds (dark)."""
        if self.occupancy is not None and hasattr(self.occupancy, "plot"):
            return self.occupancy.plot(ax, obstacle_color=obstacle_color)
        xmin, ymin, xmax, ymax = bounds = self.outline.bounds
        pad = 0.05 * max(xmax - xmin, ymax - ymin, 1e-9)
        frame = box(xmin - pad, ymin - pad, xmax + pad, ymax + pad)
        fill_polygons(ax, frame.difference(self.free), facecolor=obstacle_color, edgecolor="none")
        fill_polygons(ax, self.free, facecolor=free_color, edgecolor="none")
        return frame_map(ax, bounds, pad)
