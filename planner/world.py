"""Corridor maps, body footprints and the train description used by the planner.

A :class:`World` is free space in the plane: the inside of an optional outline polygon
(``free``) minus any number of obstacle polygons (``obstacles`` and ``walls`` are synonyms).
Everything is plain data (lists of ``[x, y]`` points, metres) so a scenario file can hold it.

Bodies are rectangles attached to their axle midpoints (the robot's centre for body 0): a
:class:`BodyFootprint` is ``length`` along the body heading, ``width`` across it, and ``offset``,
the signed distance [m] from the axle midpoint to the rectangle's centre along the heading
``theta`` (positive toward the robot, the chain convention of :mod:`pushtrain.core.kinematics`).
"""

from __future__ import annotations

import logging
import math
import re
import threading
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Point, Polygon, box
from shapely.ops import unary_union
from shapely.validation import explain_validity

from pushtrain.core.kinematics import ChainGeometry
from pushtrain.errors import PlanningInputError

from .distance_field import DEFAULT_RESOLUTION, DistanceField
from .raster import polygon_path

__all__ = ["World", "BodyFootprint", "Train", "save_diagnostic", "draw_poses",
           "polygon_from_points"]

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
        :data:`~pushtrain.planner.distance_field.DEFAULT_RESOLUTION`)."""
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

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "World":
        """Build a world from a scenario file's ``[world]`` section (plain data, metres).

        Accepted keys:

        ``free``
            ``[[x, y], ...]``: outline of the free space (a simple polygon, either orientation;
            one that crosses or touches itself is repaired by ``make_valid``, with a warning:
            two rooms touching along a wall become two parts. A scenario's ``map.free`` is
            refused instead, by :func:`~pushtrain.planner.mapworld.map_world`).
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

    def wall_distance(self, geoms) -> np.ndarray:
        """Distance [m] from each of ``geoms`` (shapely geometries, any array shape) to the
        free space's boundary (the walls), as ``shapely.distance(free.boundary, geoms)`` but
        through an STRtree of the boundary cut into short pieces, built once: a SLAM map's
        boundary has thousands of rings, and GEOS measures a plain multi-line against every
        one of them (seconds for a path's footprints on an office floor)."""
        geoms = np.asarray(geoms, dtype=object)
        tree = self._fields.get("wall_tree")
        if tree is None:
            pieces = []
            for ring in shapely.get_parts(shapely.get_rings(shapely.get_parts(self.free))):
                xy = shapely.get_coordinates(ring)
                for i in range(0, len(xy) - 1, 16):
                    pieces.append(shapely.linestrings(xy[i:i + 17]))
            tree = shapely.STRtree(pieces) if pieces else None
            self._fields["wall_tree"] = tree
        out = np.full(geoms.shape, np.inf)
        if tree is None or not geoms.size:
            return out
        flat = geoms.reshape(-1)
        (index, _), dist = tree.query_nearest(flat, return_distance=True, all_matches=False)
        result = np.full(flat.size, np.inf)
        np.minimum.at(result, index, dist)
        out.reshape(-1)[:] = result
        return out

    def eroded(self, margin: float):
        """Free space shrunk by ``margin`` [m] (prepared): a body inside it keeps that clearance.
        With an occupancy grid: where its distance field is at least ``margin``, traced
        (:func:`pushtrain.planner.raster.clear_region`; exact to the grid's resolution, like the
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
                    from .raster import clear_region

                    shared = clear_region(self.distance_field(), margin).intersection(self.free)
                else:
                    shared = self.free.buffer(-margin, quad_segs=16)
                self._fields[("eroded", margin)] = shared
            geom = shapely.from_wkb(shapely.to_wkb(shared))
            shapely.prepare(geom)
            self._fields[own] = geom
        return geom

    def with_obstacles(self, extra: Sequence[Polygon]) -> "World":
        """A copy with ``extra`` obstacle polygons added. An occupancy grid that can burn
        polygons in (:meth:`pushtrain.planner.maps.OccupancyGrid.burn`) gets them burned in;
        any other is dropped, and the copy's distance field comes from its polygons."""
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
            xmin, ymin, xmax, ymax = self.outline.bounds
            return (f"{where} lies outside {self.outline_label or 'the outline'} (x from "
                    f"{xmin:g} to {xmax:g} m, y from {ymin:g} to {ymax:g} m)")
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
        from matplotlib.patches import PathPatch

        if self.occupancy is not None and hasattr(self.occupancy, "plot"):
            return self.occupancy.plot(ax, obstacle_color=obstacle_color)
        xmin, ymin, xmax, ymax = self.outline.bounds
        pad = 0.05 * max(xmax - xmin, ymax - ymin, 1e-9)
        frame = box(xmin - pad, ymin - pad, xmax + pad, ymax + pad)
        blocked = frame.difference(self.free)
        for geom, color in ((blocked, obstacle_color), (self.free, free_color)):
            for poly in getattr(geom, "geoms", [geom]):
                if not isinstance(poly, Polygon) or poly.is_empty:
                    continue
                ax.add_patch(PathPatch(polygon_path(poly), facecolor=color, edgecolor="none"))
        ax.set_xlim(xmin - pad, xmax + pad)
        ax.set_ylim(ymin - pad, ymax + pad)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        return ax


@dataclass(frozen=True)
class BodyFootprint:
    """Rectangle of one body in its own frame.

    Parameters
    ----------
    length : float
        Extent along the body heading [m], > 0.
    width : float
        Extent across the body heading [m], > 0.
    offset : float
        Rectangle centre minus axle midpoint along the heading theta (toward the robot) [m];
        must keep the axle midpoint inside the rectangle (|offset| <= length / 2).
    """

    length: float = 0.8
    width: float = 0.6
    offset: float = 0.0

    def __post_init__(self):
        for name in ("length", "width"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0.0):
                raise PlanningInputError(f"footprint {name} = {value!r} m: must be finite and > 0")
        if not (np.isfinite(self.offset) and abs(self.offset) <= 0.5 * self.length):
            raise PlanningInputError(
                f"footprint offset = {self.offset!r} m: the axle midpoint must lie inside the "
                f"rectangle, |offset| <= length/2 = {0.5 * self.length}"
            )

    def corners(self, x, y, theta) -> np.ndarray:
        """Corners [m] of the rectangle at axle-midpoint poses; shape (..., 4, 2), CCW order."""
        x, y, theta = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (x, y, theta)))
        c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]
        hl, hw = 0.5 * self.length, 0.5 * self.width
        along = self.offset + np.array([hl, -hl, -hl, hl])
        across = np.array([hw, hw, -hw, -hw])
        px = x[..., None] + along * c - across * s
        py = y[..., None] + along * s + across * c
        return np.stack([px, py], axis=-1)

    def corner_points(self, x: float, y: float, theta: float) -> tuple:
        """Corners of the rectangle at one pose as four (x, y) tuples [m], the order of
        :meth:`corners` (a fast scalar form for the planner's validity checks)."""
        c, s = math.cos(theta), math.sin(theta)
        hl, hw = 0.5 * self.length, 0.5 * self.width
        front, back = self.offset + hl, self.offset - hl
        return ((x + front * c - hw * s, y + front * s + hw * c),
                (x + back * c - hw * s, y + back * s + hw * c),
                (x + back * c + hw * s, y + back * s - hw * c),
                (x + front * c + hw * s, y + front * s - hw * c))

    def polygons(self, x, y, theta) -> np.ndarray:
        """Shapely polygons of the rectangle at the given poses (array of the broadcast shape)."""
        return shapely.polygons(self.corners(x, y, theta))

    def to_dict(self) -> dict:
        """Plain data."""
        return {"length": self.length, "width": self.width, "offset": self.offset}


@dataclass(frozen=True)
class Train:
    """Geometry, footprints and joint limit of a robot with n trailers.

    Parameters
    ----------
    geometry : ChainGeometry
        Hitch links F_i, R_i [m].
    robot : BodyFootprint
        Body 0 (its reference point is the robot centre).
    trailers : tuple of BodyFootprint
        Bodies 1..n, one per trailer (own sizes allowed).
    phi_max : float
        Limit on every |phi_i| [rad] (the FMU's ``phi_max``), in (0, pi).
    """

    geometry: ChainGeometry
    robot: BodyFootprint = BodyFootprint(0.6, 0.5, 0.0)
    trailers: tuple = ()
    phi_max: float = 0.5 * np.pi

    def __post_init__(self):
        trailers = tuple(self.trailers) or (BodyFootprint(),) * self.geometry.n
        if len(trailers) != self.geometry.n:
            raise PlanningInputError(
                f"{len(trailers)} trailer footprints for a chain of n = {self.geometry.n} trailers"
            )
        object.__setattr__(self, "trailers", trailers)
        if not (np.isfinite(self.phi_max) and 0.0 < self.phi_max < np.pi):
            raise PlanningInputError(f"phi_max = {self.phi_max!r} rad: allowed is (0, pi)")

    @classmethod
    def uniform(
        cls,
        n_trailers: int = 3,
        link: float = 0.52,
        robot: BodyFootprint | None = None,
        trailer: BodyFootprint | None = None,
        phi_max: float = 0.5 * np.pi,
    ) -> "Train":
        """``n_trailers`` equal trailers (Table 1 defaults: 0.8 m x 0.6 m, D = 0.52 m)."""
        geometry = ChainGeometry.uniform(n_trailers, link)
        return cls(
            geometry,
            robot or BodyFootprint(0.6, 0.5, 0.0),
            (trailer or BodyFootprint(),) * geometry.n,
            phi_max,
        )

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "Train":
        """From plain data: ``n_trailers`` (int), optional ``link`` (m, default 0.52) or
        ``front``/``rear`` lists, ``robot`` and ``trailer`` (one dict for all) or ``trailers``
        (a list of dicts) with ``length``/``width``/``offset``, and ``phi_max_deg``."""
        if "front" in data or "rear" in data:
            geometry = ChainGeometry(np.asarray(data["front"]), np.asarray(data["rear"]))
        else:
            geometry = ChainGeometry.uniform(int(data.get("n_trailers", 3)), data.get("link", 0.52))
        robot = BodyFootprint(**data["robot"]) if "robot" in data else BodyFootprint(0.6, 0.5)
        if "trailers" in data:
            trailers = tuple(BodyFootprint(**t) for t in data["trailers"])
        else:
            trailers = (BodyFootprint(**data.get("trailer", {})),) * geometry.n
        phi_max = np.radians(float(data.get("phi_max_deg", 90.0)))
        return cls(geometry, robot, trailers, phi_max)

    @property
    def n(self) -> int:
        """Number of trailers."""
        return self.geometry.n

    @property
    def bodies(self) -> tuple:
        """Footprints of bodies 0..n."""
        return (self.robot, *self.trailers)

    @property
    def last(self) -> BodyFootprint:
        """Footprint of the last trailer (the planned body)."""
        return self.trailers[-1]

    def max_link(self) -> float:
        """Largest hitch link max(F_i, R_i) [m]."""
        return float(max(self.geometry.front.max(), self.geometry.rear.max()))


def draw_poses(ax, train: Train, x, y, theta, color="tab:blue", alpha=0.6, label=None):
    """Outline every body of ``train`` at positions ``x, y`` (n+1,) and headings (n+1,)."""
    for i, body in enumerate(train.bodies):
        c = body.corners(x[i], y[i], theta[i])
        ax.fill(c[:, 0], c[:, 1], facecolor="none", edgecolor=color, alpha=alpha,
                label=label if i == 0 else None)


_FAILURE_STYLE = {"collision": ("x", "red"), "self_collision": ("s", "darkorange"),
                  "joint_limit": ("^", "purple"), "pull_rule": ("v", "teal"),
                  "goal_missed": ("o", "brown")}


def save_diagnostic(path, world: World, start=None, goal=None, train: Train | None = None,
                    poses=None, title: str | None = None, marks=None,
                    failure: dict | None = None) -> None:
    """Save a PNG of the map with the last trailer at ``start`` and ``goal`` (x, y, theta).

    ``poses`` (N, 3) draws a path of the last trailer; ``marks`` is a list of (x, y, text)
    points to flag (collisions, ...). ``failure`` is the ``details`` of a PlanningError of the
    whole-train planner: its explored tree (``tree``: the last trailer's traces), the best
    partial plan (``closest``), the points where motions failed (``failure_points``, marked by
    kind and body) and the keep-out band of every clearance (``margins``: the free space shrunk
    by each margin, dashed). No pyplot: safe in headless processes.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 8))
    ax = fig.add_subplot()
    world.plot(ax)
    last = train.last if train is not None else BodyFootprint()
    if failure:
        _draw_failure(ax, world, failure, start)
        closest = failure.get("closest") or {}
        if train is not None and closest.get("x") is not None:
            draw_poses(ax, train, closest["x"], closest["y"], closest["headings"],
                       color="tab:blue", alpha=0.9, label="train at the best partial plan")
    for pose, color, name in ((start, "tab:green", "start"), (goal, "tab:red", "goal")):
        if pose is None:
            continue
        c = last.corners(*pose[:3])
        ax.fill(c[:, 0], c[:, 1], facecolor=color, alpha=0.4, edgecolor=color, label=name)
        ax.annotate("", xy=(pose[0] + 0.4 * np.cos(pose[2]), pose[1] + 0.4 * np.sin(pose[2])),
                    xytext=(pose[0], pose[1]), arrowprops={"arrowstyle": "->", "color": color})
    if poses is not None:
        poses = np.asarray(poses)
        ax.plot(poses[:, 0], poses[:, 1], "-", color="tab:blue", lw=1, label="last trailer")
    for x, y, text in marks or []:
        ax.plot([x], [y], "x", color="magenta", ms=10)
        ax.annotate(text, (x, y), color="magenta", fontsize=8)
    ax.legend(loc="best", fontsize=8)
    if title:
        ax.set_title(title, fontsize=9)
    fig.savefig(path, dpi=110)


def _draw_failure(ax, world: World, details: dict, start) -> None:
    """The search's tree, failure points, best partial plan, keep-out margins, the route
    through the building and the bottleneck on ``ax``."""
    route = details.get("route")
    if route and route.get("points"):
        xy = np.asarray(route["points"], dtype=float)
        ax.plot(xy[:, 0], xy[:, 1], "-", color="tab:green", lw=2.0, alpha=0.5,
                label=f"route ({route['length']:.1f} m)")
    bottleneck = details.get("bottleneck")
    what = "bottleneck"
    if not bottleneck and route:
        bottleneck, what = route.get("bottleneck"), "narrowest on the route"
    if bottleneck:
        ax.plot([bottleneck["x"]], [bottleneck["y"]], "o", ms=14, mfc="none", mew=2,
                color="crimson", label=f"{what}: {bottleneck['width']:.2f} m wide, "
                f"{bottleneck['needed']:.2f} m needed")
    for k, trace in enumerate(details.get("tree") or []):
        xy = np.asarray(trace, dtype=float)
        if xy.ndim == 2 and xy.shape[0] > 1:
            ax.plot(xy[:, 0], xy[:, 1], "-", color="0.6", lw=0.5,
                    label="explored (last trailer)" if k == 0 else None)
    for m in sorted(set(details.get("margins") or [])):
        if m <= 0.0:
            continue
        band = world.eroded(m)
        for k, poly in enumerate(getattr(band, "geoms", [band])):
            for ring in [poly.exterior, *poly.interiors]:
                xy = np.asarray(ring.coords)
                ax.plot(xy[:, 0], xy[:, 1], "--", color="tab:orange", lw=0.7,
                        label=f"keep-out {m:.3f} m" if k == 0 and ring is poly.exterior
                        else None)
    seen = set()
    for p in details.get("failure_points") or []:
        kind = p.get("kind", "collision").replace("verification_", "")
        marker, color = _FAILURE_STYLE.get(kind, ("x", "red"))
        label = kind.replace("_", " ") if kind not in seen else None
        seen.add(kind)
        ax.plot([p["x"]], [p["y"]], marker, color=color, ms=5, mfc="none", label=label)
    closest = details.get("closest")
    if closest and closest.get("segments") and start is not None:
        from pushtrain.core.reference import Segment, path_points

        x, y = path_points(start, [Segment.from_dict(g) for g in closest["segments"]])
        ax.plot(x, y, "-", color="tab:blue", lw=2, label="best partial plan")
    if details.get("failure_points"):
        worst = {}
        for p in details["failure_points"]:
            if "body" in p:
                worst[p["body"]] = worst.get(p["body"], 0) + 1
        if worst:
            body = max(worst, key=worst.get)
            last = [p for p in details["failure_points"] if p.get("body") == body][-1]
            name = "robot" if body == 0 else f"trailer {body}"
            ax.annotate(f"{name} ({worst[body]} failures)", (last["x"], last["y"]),
                        color="red", fontsize=8)
