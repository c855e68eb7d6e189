"""The route through the building: where the train goes, before how it manoeuvres.

A tugger driver crossing a building first knows the way (down this corridor, left at the hall,
through that door) and only then thinks about the manoeuvres at the junctions, doors and docks.
:class:`Route` is that way for the whole-train search (:mod:`~pushtrain.planner.lattice`):

Grid
    The map's distance field sampled on a grid of at most :data:`MAX_ROUTE_NODES` nodes
    (:data:`MIN_CELL`, 5 cm, on a 30 m x 30 m map, coarser on larger ones). A node is open
    when the last trailer fits there with its clearance (``half_width``: half its width plus
    its margin; it leads the train into every place the train goes), relaxed by half a cell
    diagonal so that sampling never closes a passage.
Cost
    An 8-connected Dijkstra from the goal (scipy's compiled one) whose edges cost their length
    times ``1 + centre_weight * max(0, 1 - (d - half_width) / centre_band)``: a driver keeps to
    the middle of a corridor and away from wall corners, so the route does too, where the
    corridor is wider than the train by less than ``centre_band``.
Route
    The predecessors from the start to the goal, as a polyline of node centres, smoothed
    (a moving average over ``smooth`` metres, the ends kept) and resampled every
    :data:`SPACING` metres, with its heading of travel and the free half-width beside it.

The route's own distance from the walls (``half_width``) is no passage's width: a smoothed route
cuts the inside of corners. What a way is wide enough for is :mod:`~pushtrain.planner.passage`'s
(the widest way's narrowest place, measured on the map).

All lengths in metres, angles in radians; headings here are directions of *travel* (the chain
convention's theta of a pushed train is the travel direction plus pi).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from pushtrain.facility.distance_field import DistanceField

__all__ = ["Route", "MAX_ROUTE_NODES", "SPACING", "find_route", "comes_in_across",
           "starts_against", "passes_back", "loop_route", "grid_graph", "undirected_graph"]

MAX_ROUTE_NODES = 400_000
"""Most nodes of the route's grid (about 26 MB of graph): a 100 m x 100 m map gets 16 cm cells."""

SPACING = 0.1
"""Spacing [m] of the route's resampled points."""

MIN_CELL = 0.05
"""Finest cell [m] of the route's grid: a guide needs no finer (the heuristic's grid is as
coarse), and a polygon map's 2 cm distance field would make it six times dearer. The widest
way's bottleneck (:func:`~pushtrain.planner.passage.widest_gap`) keeps the field's own
resolution: it measures."""


@dataclass(frozen=True)
class Route:
    """A route of the train from the start to the goal (see the module docstring).

    Attributes
    ----------
    points : (m, 2) array
        Positions [m] every about :data:`SPACING` m, from the start to the goal.
    s : (m,) array
        Length [m] along the route at each point.
    heading : (m,) array
        Direction of travel [rad] at each point.
    half_width : (m,) array
        Distance [m] from each point to the nearest wall.
    needed : float
        Half the width [m] the train needs (the last trailer's width plus its clearance).
    loop : bool
        The route goes round a loop (:func:`loop_route`) and may pass a place twice, in
        opposite directions: a point is projected onto the stretch travelled its way.
    """

    points: np.ndarray
    s: np.ndarray
    heading: np.ndarray
    half_width: np.ndarray
    needed: float
    loop: bool = False

    @property
    def length(self) -> float:
        return float(self.s[-1])

    def project(self, x: float, y: float, travel: float | None = None) -> tuple[float, float]:
        """(length along the route [m], distance from it [m]) of the point nearest to (x, y);
        on a loop with ``travel`` (a direction of travel [rad]), the nearest of the points
        travelled within 90 degrees of it."""
        d2 = (self.points[:, 0] - x) ** 2 + (self.points[:, 1] - y) ** 2
        if self.loop and travel is not None:
            against = np.abs(np.remainder(self.heading - travel + math.pi, 2.0 * math.pi)
                             - math.pi) > 0.5 * math.pi
            d2 = np.where(against, np.inf, d2)
        i = int(np.argmin(d2))
        return float(self.s[i]), math.sqrt(float(d2[i]))

    def turn(self, s0: float, s1: float) -> float:
        """The largest change of the direction of travel [rad] from length ``s0`` to any
        point up to ``s1`` [m] along the route."""
        last = len(self.s) - 1
        i0, i1 = (min(int(i), last) for i in np.searchsorted(self.s, [s0, s1]))
        stretch = self.heading[i0:max(i1, i0) + 1]
        return float(np.abs(stretch - self.heading[i0]).max())

    def pose_at(self, s: float) -> tuple[float, float, float]:
        """(x, y, direction of travel) [m, m, rad] at length ``s`` [m] along the route."""
        s = min(max(float(s), 0.0), self.length)
        i = int(np.searchsorted(self.s, s, side="right")) - 1
        i = min(max(i, 0), len(self.s) - 2)
        span = self.s[i + 1] - self.s[i]
        a = 0.0 if span <= 0.0 else (s - self.s[i]) / span
        x, y = (1.0 - a) * self.points[i] + a * self.points[i + 1]
        dth = math.remainder(float(self.heading[i + 1] - self.heading[i]), 2.0 * math.pi)
        return float(x), float(y), float(self.heading[i] + a * dth)

    def to_dict(self) -> dict:
        """Plain data (for the diagnostics and the picture)."""
        return {"points": self.points[:: max(1, len(self.points) // 400)].tolist()
                + [self.points[-1].tolist()], "length": self.length}


class _Grid:
    """The route's grid over a distance field: nodes, their free distance and open mask."""

    def __init__(self, field: DistanceField, half_width: float, max_nodes: int,
                 min_cell: float = 0.0, avoid: tuple = ()):
        xmin, ymin, xmax, ymax = field.bounds
        h = max(field.resolution, min_cell, math.sqrt((xmax - xmin) * (ymax - ymin) / max_nodes))
        self.h, self.x0, self.y0 = h, xmin, ymin
        nx = int(math.floor((xmax - xmin) / h)) + 1
        ny = int(math.floor((ymax - ymin) / h)) + 1
        xs = xmin + h * np.arange(nx)
        ys = ymin + h * np.arange(ny)
        self.d = field.at(xs[None, :], ys[:, None])
        self.open = self.d >= half_width - h * math.sqrt(0.5)
        for ax, ay, radius in avoid:
            self.open &= (xs[None, :] - ax) ** 2 + (ys[:, None] - ay) ** 2 > radius ** 2
        self.ii, self.jj, self.index, *self._graph = grid_graph(self.open, h)

    def cell(self, x: float, y: float) -> tuple[int, int]:
        ny, nx = self.open.shape
        return (min(max(int(round((y - self.y0) / self.h)), 0), ny - 1),
                min(max(int(round((x - self.x0) / self.h)), 0), nx - 1))

    def nearest_open(self, x: float, y: float, within: float) -> int | None:
        """Index of the open node nearest to (x, y) within ``within`` [m], None if none."""
        i, j = self.cell(x, y)
        r = int(math.ceil(within / self.h))
        ny, nx = self.open.shape
        i0, i1, j0, j1 = max(i - r, 0), min(i + r + 1, ny), max(j - r, 0), min(j + r + 1, nx)
        window = self.open[i0:i1, j0:j1]
        if not window.any():
            return None
        wi, wj = np.nonzero(window)
        d2 = (wi + i0 - (y - self.y0) / self.h) ** 2 + (wj + j0 - (x - self.x0) / self.h) ** 2
        k = int(np.argmin(d2))
        if d2[k] * self.h ** 2 > within ** 2:
            return None
        return int(self.index[wi[k] + i0, wj[k] + j0])

    def edges(self):
        """(rows, cols, lengths [m], mean free distance [m]) of the 8-connected open edges."""
        rows, cols, lengths = self._graph
        ii, jj = self.ii, self.jj
        dist = 0.5 * (self.d[ii[rows], jj[rows]] + self.d[ii[cols], jj[cols]])
        return rows, cols, lengths, dist


def grid_graph(open_mask: np.ndarray, h: float):
    """The 8-connected graph of the ``open_mask`` (ny, nx) nodes of a grid of spacing ``h``
    [m]: (ii, jj) the open nodes' rows and columns, ``index`` (ny, nx) their numbers (-1 where
    closed), and each edge once as (rows, cols, lengths [m]), in the order right, up,
    up-right, up-left."""
    ny, nx = open_mask.shape
    ii, jj = np.nonzero(open_mask)
    index = np.full((ny, nx), -1, dtype=np.int64)
    index[ii, jj] = np.arange(ii.size)
    rows, cols, lengths = [], [], []
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        # the nodes (i, j) whose neighbour (i + di, j + dj) exists, and those neighbours: two
        # views of the grid; both open, in row-major order of (i, j) like np.nonzero's
        a = (slice(0, ny - di), slice(max(0, -dj), nx - max(0, dj)))
        b = (slice(di, ny), slice(max(0, dj), nx + min(0, dj)))
        ok = open_mask[a] & open_mask[b]
        rows.append(index[a][ok])
        cols.append(index[b][ok])
        lengths.append(np.full(rows[-1].size, h * math.hypot(di, dj)))
    return ii, jj, index, np.concatenate(rows), np.concatenate(cols), np.concatenate(lengths)


def undirected_graph(rows, cols, weights, m: int) -> csr_matrix:
    """The (m, m) sparse matrix of the edges (rows, cols) of ``weights`` in both directions,
    for scipy's Dijkstra."""
    return csr_matrix((np.concatenate([weights, weights]),
                       (np.concatenate([rows, cols]), np.concatenate([cols, rows]))),
                      shape=(m, m))


def find_route(field: DistanceField, start, goal, half_width: float, *,
               centre_band: float = 0.6, centre_weight: float = 2.0, smooth: float = 1.0,
               max_nodes: int = MAX_ROUTE_NODES, avoid: tuple = ()) -> Route | None:
    """The route from ``start`` to ``goal`` (x, y, ...) [m] where a body of ``half_width``
    [m] (half its width plus its clearance) fits (see the module docstring); None if there is
    none (see :func:`~pushtrain.planner.passage.widest_gap` for why). ``avoid``: discs
    (x, y, radius) [m] the route may not enter (corners the train cannot turn)."""
    grid = _Grid(field, half_width, max_nodes, MIN_CELL, avoid)
    if grid.ii.size < 2:
        return None
    a = grid.nearest_open(start[0], start[1], 3.0 * grid.h + 0.5)
    b = grid.nearest_open(goal[0], goal[1], 3.0 * grid.h + 0.5)
    if a is None or b is None:
        return None
    r, c, length, dist = grid.edges()
    excess = np.clip(1.0 - (dist - half_width) / centre_band, 0.0, 1.0)
    w = length * (1.0 + centre_weight * excess)
    graph = undirected_graph(r, c, w, grid.ii.size)
    cost, pred = dijkstra(graph, directed=False, indices=b, return_predecessors=True)
    if not math.isfinite(cost[a]):
        return None
    chain = [a]
    while chain[-1] != b:
        chain.append(int(pred[chain[-1]]))
    xy = np.column_stack([grid.x0 + grid.h * grid.jj[chain], grid.y0 + grid.h * grid.ii[chain]])
    xy[0] = start[:2]
    xy[-1] = goal[:2]
    return _route_from_polyline(xy, field, half_width, smooth)


def starts_against(route: Route, start, angle: float = 0.5 * math.pi) -> bool:
    """Whether ``route``'s direction of travel over its first metre differs from the direction
    the train is pushed at ``start`` (x, y, theta; chain convention) by more than ``angle``
    [rad]: the train must turn round (its goal is behind it)."""
    if route.length < 0.2:
        return False
    x, y, _ = route.pose_at(min(1.0, route.length))
    travel_out = math.atan2(y - float(start[1]), x - float(start[0]))
    pushed = float(start[2]) + math.pi
    return abs(math.remainder(pushed - travel_out, 2.0 * math.pi)) > angle


def passes_back(route: Route, start, within: float = 1.0) -> bool:
    """Whether ``route`` comes back within ``within`` [m] of ``start`` (x, y, theta; chain
    convention) travelling against the train's start direction: a loop round an island or a
    hall and back out of the way the train came in (not merely another way to a far goal)."""
    away = float(start[2])  # the start's direction of travel (theta + pi) reversed
    along, off = route.project(float(start[0]), float(start[1]), away)
    return off <= within and along > within


def loop_route(points: np.ndarray, field: DistanceField, half_width: float,
               smooth: float = 1.0) -> Route:
    """The route along ``points`` ((m, 2) [m]: a way round a loop from the start to the
    goal, :meth:`~pushtrain.planner.heuristic.Heuristic.build_loop`), smoothed and resampled
    like :func:`find_route`'s."""
    return _route_from_polyline(np.asarray(points, dtype=float), field, half_width, smooth,
                                loop=True)


def comes_in_across(route: Route, goal, angle: float) -> bool:
    """Whether ``route``'s direction of travel over its last metre differs from the direction
    a train is pushed at ``goal`` (x, y, theta; chain convention: theta + pi) by more than
    ``angle`` [rad]: the route comes in across the goal (up a corridor into a T junction whose
    goal faces along the hall), so no push along it gets the train there."""
    if route.length < 1.0:
        return False
    travel_in = route.pose_at(route.length - 1.0)[2]
    pushed = float(goal[2]) + math.pi
    return abs(math.remainder(pushed - travel_in, 2.0 * math.pi)) > angle


def _route_from_polyline(xy: np.ndarray, field: DistanceField, needed: float,
                         smooth: float, loop: bool = False) -> Route:
    """Resample the node polyline every :data:`SPACING` m, smooth it over ``smooth`` m (the
    ends kept), and measure its headings and free half-widths."""
    xy = _resample(xy, SPACING)
    k = max(1, int(round(0.5 * smooth / SPACING)))
    if len(xy) > 2 * k + 2:
        kernel = np.ones(2 * k + 1) / (2 * k + 1)
        padded = np.vstack([np.repeat(xy[:1], k, axis=0), xy, np.repeat(xy[-1:], k, axis=0)])
        sm = np.column_stack([np.convolve(padded[:, 0], kernel, mode="valid"),
                              np.convolve(padded[:, 1], kernel, mode="valid")])
        sm[0], sm[-1] = xy[0], xy[-1]
        xy = _resample(sm, SPACING)
    d = np.diff(xy, axis=0)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(d[:, 0], d[:, 1]))])
    heading = np.arctan2(d[:, 1], d[:, 0])
    heading = np.unwrap(np.concatenate([heading, heading[-1:]]))
    half = field.at(xy[:, 0], xy[:, 1])
    return Route(xy, s, heading, half, float(needed), loop)


def _resample(xy: np.ndarray, spacing: float) -> np.ndarray:
    """The polyline ``xy`` resampled at about ``spacing`` [m] (its ends kept)."""
    d = np.diff(xy, axis=0)
    seg = np.hypot(d[:, 0], d[:, 1])
    keep = np.concatenate([[True], seg > 1e-12])
    xy = xy[keep]
    s = np.concatenate([[0.0], np.cumsum(seg[seg > 1e-12])])
    if s[-1] <= 0.0:
        return xy[:1].repeat(2, axis=0)
    m = max(2, int(math.ceil(s[-1] / spacing)) + 1)
    t = np.linspace(0.0, s[-1], m)
    return np.column_stack([np.interp(t, s, xy[:, 0]), np.interp(t, s, xy[:, 1])])
