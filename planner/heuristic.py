"""Cost-to-go estimates of the whole-train search: Reeds-Shepp length and the map's own distance.

Two lower bounds on the length the last trailer still has to travel, each blind where the other
sees:

Reeds-Shepp (:meth:`Heuristic.rs`)
    The shortest line-and-arc path of turning radius ``radius`` from the reference's pose to
    the goal, ignoring walls (OMPL's ``ReedsSheppStateSpace.distance``, a few microseconds).
    It sees headings and the turning radius; it does not see that the way around a wall is long.
Obstacle-aware distance (:meth:`Heuristic.grid`)
    Dijkstra from the goal over the cells of a grid (``resolution``) where the last trailer's
    axle midpoint can be: where the map's signed distance is at least the trailer's
    ``half_width + margin`` (its midpoint is that far inside the rectangle), relaxed by one cell
    diagonal so that a narrow passage is never cut by the sampling. 8-connected, edge lengths
    the cell distances (scipy's compiled Dijkstra). It sees the walls; not the headings.

The search takes the larger of the two (both admissible up to the grid's resolution).
Positions on no reachable cell have no finite estimate: the goal cannot be reached from there.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from pushtrain.facility.distance_field import DistanceField

from .curves import reeds_shepp_space
from .route import grid_graph

__all__ = ["Heuristic", "CarGrid", "MAX_NODES", "MAX_CAR_CELLS"]

MAX_NODES = 400_000
"""Most nodes of the 2-D distance grid (a 30 m x 30 m map at 5 cm); larger maps get coarser
cells."""

MAX_CAR_CELLS = 20_000
"""Most cells of the :class:`CarGrid` (x 24 headings x 2 gears states; a 35 m x 35 m map at
0.25 m); larger maps get coarser cells."""


class Heuristic:
    """Estimates of the remaining length [m] to ``goal`` (x, y, theta; chain convention).

    Parameters
    ----------
    field : DistanceField
        The map's signed distance field.
    goal : (x, y, theta)
        Goal pose of the last trailer [m, m, rad].
    radius : float
        Turning radius [m] of the Reeds-Shepp estimate.
    clearance : float
        Distance [m] from walls the last trailer's axle midpoint needs (its half width plus
        its margin, or less where the rectangle is shorter than wide).
    resolution : float
        Cell size [m] of the grid of the obstacle-aware distance.
    car_resolution : float or None
        Cell size [m] of the :class:`CarGrid` (None: none).
    car : dict or None
        Further settings of the :class:`CarGrid` (``headings``, ``turn_weight``, ...).
    build_car : bool
        Build the :class:`CarGrid` now (else on :meth:`build_car`).
    max_nodes : int
        About the most nodes of the obstacle-aware grid (1000 to :data:`MAX_NODES`): its
        Dijkstra run cannot be interrupted, so a short time budget asks for a coarser grid.
    """

    def __init__(self, field: DistanceField, goal, radius: float, clearance: float,
                 resolution: float = 0.05, car_resolution: float | None = 0.25,
                 car: dict | None = None, build_car: bool = True,
                 max_nodes: int = MAX_NODES):
        self.goal = tuple(float(a) for a in goal)
        self.radius = float(radius)
        xmin, ymin, xmax, ymax = field.bounds
        margin_bounds = (xmin - 10.0, ymin - 10.0, xmax + 10.0, ymax + 10.0)
        self._space = reeds_shepp_space(self.radius, margin_bounds)
        self._a = self._space.allocState()
        self._b = self._space.allocState()
        self._b.setX(self.goal[0])
        self._b.setY(self.goal[1])
        self._b.setYaw(_yaw(self.goal[2]))
        # at most max_nodes grid nodes: a large map gets a coarser grid
        nodes = max(1000, min(int(max_nodes), MAX_NODES))
        h = max(float(resolution), math.sqrt((xmax - xmin) * (ymax - ymin) / nodes))
        self.resolution = h
        nx = int(math.floor((xmax - xmin) / h)) + 1
        ny = int(math.floor((ymax - ymin) / h)) + 1
        self.x0, self.y0 = xmin, ymin
        xs = xmin + h * np.arange(nx)
        ys = ymin + h * np.arange(ny)
        d = field.at(xs[None, :], ys[:, None])
        free = d >= clearance - h * math.sqrt(0.5)
        self.free = free
        self.distance = _dijkstra(free, self._cell(self.goal[0], self.goal[1]), h)
        self.car = None
        self._car_args = (field, clearance, car_resolution, car or {})
        if build_car:
            self.build_car()

    def car_states(self) -> int:
        """About how many states the :class:`CarGrid` has (0 if none is configured)."""
        field, clearance, hc, options = self._car_args
        if hc is None:
            return 0
        xmin, ymin, xmax, ymax = field.bounds
        cells = min((xmax - xmin) * (ymax - ymin) / float(hc) ** 2, MAX_CAR_CELLS)
        return int(cells * float(np.mean(self.free)) * options.get("headings", 24) * 2)

    def build_car(self) -> None:
        """Build the :class:`CarGrid` estimate (once; a few tenths of a second on a large map),
        used by :meth:`__call__` from then on."""
        field, clearance, hc, options = self._car_args
        if self.car is not None or hc is None:
            return
        xmin, ymin, xmax, ymax = field.bounds
        hc = max(float(hc), math.sqrt((xmax - xmin) * (ymax - ymin) / MAX_CAR_CELLS))
        xc = xmin + hc * np.arange(int(math.floor((xmax - xmin) / hc)) + 1)
        yc = ymin + hc * np.arange(int(math.floor((ymax - ymin) / hc)) + 1)
        free_c = field.at(xc[None, :], yc[:, None]) >= clearance - hc * math.sqrt(0.5)
        self.car = CarGrid(free_c, xmin, ymin, hc, self.goal, self.radius, **options)

    def _cell(self, x: float, y: float) -> tuple[int, int]:
        """(row, column) of the grid node nearest to (x, y), clamped to the grid."""
        ny, nx = self.free.shape
        j = min(max(int(round((x - self.x0) / self.resolution)), 0), nx - 1)
        i = min(max(int(round((y - self.y0) / self.resolution)), 0), ny - 1)
        return i, j

    def grid(self, x: float, y: float) -> float:
        """Obstacle-aware distance [m] from (x, y) to the goal (inf where unreachable): the
        best of the four surrounding grid nodes plus the way to it."""
        h = self.resolution
        u = (x - self.x0) / h
        v = (y - self.y0) / h
        ny, nx = self.free.shape
        j0 = min(max(int(math.floor(u)), 0), nx - 2)
        i0 = min(max(int(math.floor(v)), 0), ny - 2)
        best = math.inf
        for i in (i0, i0 + 1):
            for j in (j0, j0 + 1):
                dist = self.distance[i, j]
                if dist < math.inf:
                    best = min(best, dist + h * math.hypot(u - j, v - i))
        return best

    def rs(self, pose) -> float:
        """Length [m] of the shortest Reeds-Shepp path from ``pose`` (chain convention) to the
        goal."""
        self._a.setX(float(pose[0]))
        self._a.setY(float(pose[1]))
        self._a.setYaw(_yaw(pose[2]))
        return float(self._space.distance(self._a, self._b))

    def __call__(self, pose, direction: int = 0) -> float:
        """The largest of :meth:`rs`, :meth:`grid` and the :class:`CarGrid` cost (if built)."""
        g = self.grid(pose[0], pose[1])
        if g == math.inf:
            return math.inf
        best = max(g, self.rs(pose))
        if self.car is not None:
            best = max(best, self.car(pose, direction))
        return best


class CarGrid:
    """Cost-to-go of a Reeds-Shepp car among the walls: Dijkstra over (x, y, heading, gear).

    The last trailer's axle midpoint as a car of turning radius ``radius`` that drives forward
    (pushing, along theta + pi) or backward (pulling, along theta) on the grid of
    :class:`Heuristic` (the cells where the midpoint keeps its clearance), with ``headings``
    heading bins. Each move is an arc or a line of ``radius * 2 pi / headings * 2`` metres whose
    swept cells are all free; it costs its length (times ``pull_factor`` backward), plus
    ``turn_weight`` times its turn, plus ``cusp_cost`` when it changes the gear: the prices of
    the search. One Dijkstra over the reversed moves from the goal (either gear) gives every
    state's cost to the goal. Unlike the Reeds-Shepp length it knows that turning around needs
    room (a side branch, a wide spot) and a cusp; unlike the 2-D distance it knows headings.
    The grid's rounding makes it approximate (a few tenths of a metre).
    """

    def __init__(self, free: np.ndarray, x0: float, y0: float, h: float, goal, radius: float,
                 headings: int = 24, turn_weight: float = 0.3, cusp_cost: float = 2.0,
                 pull_factor: float = 1.2):
        ny, nx = free.shape
        self.free, self.x0, self.y0, self.h, self.k = free, x0, y0, h, int(headings)
        k_n = self.k
        dth = 2.0 * math.pi / k_n
        step = 2  # heading bins per arc move
        length = radius * dth * step
        ii, jj = np.nonzero(free)
        index = np.full((ny, nx), -1, dtype=np.int64)
        index[ii, jj] = np.arange(ii.size)
        m = ii.size
        ks = np.arange(k_n)
        th0 = ks * dth  # (K,)
        s_pts = np.linspace(0.0, length, 5)[1:]  # samples along a move
        rows, cols, weights = [], [], []
        cell = np.repeat(np.arange(m), k_n)  # (m K,): every free cell in every heading
        kk = np.tile(ks, m)
        for gear, sigma, factor in ((0, -1.0, 1.0), (1, 1.0, pull_factor)):
            for turn in (-1, 0, 1):
                # offsets (K, samples) of the move from each heading (chain convention:
                # sigma = -1 pushing, along theta + pi)
                if turn == 0:
                    px = sigma * s_pts[None, :] * np.cos(th0)[:, None]
                    py = sigma * s_pts[None, :] * np.sin(th0)[:, None]
                else:
                    kap = turn / radius
                    th = th0[:, None] + kap * s_pts[None, :]
                    px = sigma * (np.sin(th) - np.sin(th0)[:, None]) / kap
                    py = -sigma * (np.cos(th) - np.cos(th0)[:, None]) / kap
                di = np.rint(py / h).astype(int)[kk]  # (m K, samples)
                dj = np.rint(px / h).astype(int)[kk]
                i2 = ii[cell][:, None] + di
                j2 = jj[cell][:, None] + dj
                ok = ((i2 >= 0) & (i2 < ny) & (j2 >= 0) & (j2 < nx)).all(axis=1)
                i2c, j2c = np.clip(i2, 0, ny - 1), np.clip(j2, 0, nx - 1)
                ok &= free[i2c, j2c].all(axis=1)
                src = self._state(cell[ok], kk[ok], 0) // 2
                dst_cell = index[i2c[ok, -1], j2c[ok, -1]]
                k_end = (kk[ok] + turn * step) % k_n
                cost = length * factor + turn_weight * abs(turn) * dth * step
                for g_prev in (0, 1):
                    rows.append(src * 2 + g_prev)
                    cols.append(self._state(dst_cell, k_end, gear))
                    w = cost + (cusp_cost if g_prev != gear else 0.0)
                    weights.append(np.full(src.size, w))
        n_states = m * k_n * 2
        r = np.concatenate(rows)
        c = np.concatenate(cols)
        w = np.concatenate(weights)
        # reversed moves: the distance from the goal on the transposed graph is the cost to it
        graph = csr_matrix((w, (c, r)), shape=(n_states, n_states))
        # the goal: the cells around it (the rounding of the moves lands on any of them) in
        # the goal's heading bin and its two neighbours, either gear
        gu, gv = (goal[0] - x0) / h, (goal[1] - y0) / h
        kg = self._bin(goal[2])
        sources = []
        for gi in (int(math.floor(gv)), int(math.floor(gv)) + 1):
            for gj in (int(math.floor(gu)), int(math.floor(gu)) + 1):
                if 0 <= gi < ny and 0 <= gj < nx and free[gi, gj]:
                    sources += [self._state(index[gi, gj], (kg + dk) % k_n, g)
                                for dk in (-1, 0, 1) for g in (0, 1)]
        self.cost = np.full((ny, nx, k_n, 2), np.inf)
        if sources:
            dist = dijkstra(graph, directed=True, indices=sources, min_only=True)
            self.cost[ii, jj] = dist.reshape(m, k_n, 2)
        self._index = index

    def _state(self, cell, k: int, gear: int):
        return (cell * self.k + k) * 2 + gear

    def _cell(self, x: float, y: float) -> tuple[int, int]:
        return (int(round((y - self.y0) / self.h)), int(round((x - self.x0) / self.h)))

    def _bin(self, theta: float) -> int:
        return int(round(theta / (2.0 * math.pi / self.k))) % self.k

    def __call__(self, pose, direction: int = 0) -> float:
        """Cost [m] from ``pose`` (chain convention) with the last motion's ``direction``
        (PUSH +1, PULL -1, 0 none) to the goal; inf off the grid or where unreachable."""
        u, v = (pose[0] - self.x0) / self.h, (pose[1] - self.y0) / self.h
        ny, nx = self.free.shape
        i0, j0 = int(math.floor(v)), int(math.floor(u))
        if not (0 <= i0 < ny - 1 and 0 <= j0 < nx - 1):
            return math.inf
        k = self._bin(pose[2])
        gears = {1: [0], -1: [1]}.get(direction, [0, 1])
        # the best of the four surrounding cells, plus the way to its centre
        best = math.inf
        for i in (i0, i0 + 1):
            for j in (j0, j0 + 1):
                value = float(self.cost[i, j, k, gears].min())
                best = min(best, value + self.h * math.hypot(u - j, v - i))
        return best


def _yaw(theta: float) -> float:
    """Chain heading -> the Reeds-Shepp state's yaw (theta + pi) in [-pi, pi)."""
    return (float(theta) + 2.0 * math.pi) % (2.0 * math.pi) - math.pi


def _dijkstra(free: np.ndarray, source: tuple[int, int], h: float) -> np.ndarray:
    """Shortest 8-connected distances [m] over the ``free`` nodes from ``source`` (row, col);
    inf on blocked or unreachable nodes (and everywhere if the source is blocked)."""
    out = np.full(free.shape, np.inf)
    if not free[source]:
        return out
    ii, jj, index, r, c, w = grid_graph(free, h)
    # each edge stored once: scipy's undirected Dijkstra walks it both ways (half the matrix
    # to build; the distances are the same to the bit, being the unique fixpoint of
    # d(v) = min over neighbours u of d(u) + w(u, v))
    dist = dijkstra(csr_matrix((w, (r, c)), shape=(ii.size, ii.size)), directed=False,
                    indices=int(index[source]))
    out[ii, jj] = dist
    return out
