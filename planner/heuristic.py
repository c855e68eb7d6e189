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

from .reeds_shepp import planner_yaw, reeds_shepp_space
from .route import grid_graph

__all__ = ["Heuristic", "CarGrid", "MAX_NODES", "MAX_CAR_CELLS"]

MAX_NODES = 400_000
"""Most nodes of the 2-D distance grid (a 30 m x 30 m map at 5 cm); larger maps get coarser
cells."""

MAX_CAR_CELLS = 20_000
"""Most cells of the :class:`CarGrid` (x 24 headings x 3 gears states; a 35 m x 35 m map at
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
        self._b.setYaw(planner_yaw(self.goal[2]))
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
        self.loop = None
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
        return int(cells * float(np.mean(self.free)) * options.get("headings", 24) * GEARS)

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

    def build_loop(self, start, band: tuple = ()) -> np.ndarray | None:
        """The way round (a loop: an island, a hall to turn in) from ``start`` (x, y, theta;
        chain convention) to the goal pushing only, as the car of :class:`CarGrid` drives it
        ((m, 2) positions [m]), or None if the car cannot get there without pulling. Its arcs
        keep the clearance on the field itself, and so do the arcs of radii ``band`` [m] round
        their centres (the ring the turning train sweeps, less the clearance). When
        there is one, :meth:`__call__` takes its pushing-only cost into account from then on:
        the search is led round the loop, as a driver goes, rather than into turning on the
        spot."""
        field, clearance, hc, options = self._car_args
        if hc is None:
            return None
        grid = CarGrid(*self._car_free(field, clearance, hc), self.goal, self.radius,
                       headings=options.get("headings", 24),
                       turn_weight=options.get("turn_weight", 0.3), push_only=True,
                       band=(field, clearance, tuple(band)))
        path = grid.push_path(start)
        if path is not None:
            self.loop = grid
        return path

    @staticmethod
    def _car_free(field, clearance: float, hc: float):
        """(free cells, x0, y0, cell size) of a :class:`CarGrid` of about ``hc`` [m] cells."""
        xmin, ymin, xmax, ymax = field.bounds
        hc = max(float(hc), math.sqrt((xmax - xmin) * (ymax - ymin) / MAX_CAR_CELLS))
        xc = xmin + hc * np.arange(int(math.floor((xmax - xmin) / hc)) + 1)
        yc = ymin + hc * np.arange(int(math.floor((ymax - ymin) / hc)) + 1)
        free_c = field.at(xc[None, :], yc[:, None]) >= clearance - hc * math.sqrt(0.5)
        return free_c, xmin, ymin, hc

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
        self._a.setYaw(planner_yaw(pose[2]))
        return float(self._space.distance(self._a, self._b))

    def __call__(self, pose, direction: int = 0, straight: bool = True) -> float:
        """The largest of :meth:`rs`, :meth:`grid` and the :class:`CarGrid` cost (if built;
        ``straight``: whether the chain may pull)."""
        g = self.grid(pose[0], pose[1])
        if g == math.inf:
            return math.inf
        best = max(g, self.rs(pose))
        if self.loop is not None:
            loop = self.loop(pose, direction, straight)
            if loop < math.inf:
                best = max(best, loop)
        if self.car is not None:
            car = self.car(pose, direction, straight)
            if car < math.inf:  # the car's grid is coarse: it never rules a pose out
                best = max(best, car)
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

    The pull rule of the train is in it too: the car may change from pushing to pulling only
    after a straight push of ``straighten`` metres (the chain straightens on it), and only
    where the straight train (``train_length`` metres from the car toward the robot) fits, so a
    turnaround costs the straight run into a branch that the train needs, and is not made where
    the branch is shorter than the train. There are three gears: pushing (0), pulling (1) and
    pushed straight (2: after such a run, or a straight push after a pull); pulls start from
    gears 1 and 2 only (from any gear when ``straighten`` is 0), and states of gears 1 and 2
    are only where the straight train fits. A turnaround in a room whose branches are shorter
    than the train then costs the way round an island, as it does the train.
    """

    def __init__(self, free: np.ndarray, x0: float, y0: float, h: float, goal, radius: float,
                 headings: int = 24, turn_weight: float = 0.3, cusp_cost: float = 2.0,
                 pull_factor: float = 1.2, straighten: float = 0.0, train_length: float = 0.0,
                 push_only: bool = False, band: tuple | None = None):
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
        rows, cols, weights = [], [], []
        cell = np.repeat(np.arange(m), k_n)  # (m K,): every free cell in every heading
        kk = np.tile(ks, m)
        # (gear, sigma, turn, move length, cost factor, {gear before: gear after})
        moves = []
        for turn in (-1, 0, 1):
            after = {0: 0, 1: 0, 2: 0} if turn else {0: 0, 1: 2, 2: 2}
            moves.append((0, -1.0, turn, length, 1.0, after))
            moves.append((1, 1.0, turn, length, pull_factor,
                          {1: 1, 2: 1} if straighten > 0.0 else {0: 1, 1: 1, 2: 1}))
        if straighten > 0.0:
            long = length * max(1, math.ceil(straighten / length))
            moves.append((0, -1.0, 0, long, 1.0, {0: 2}))
        if push_only:  # a loop: the car never pulls (see push_path)
            moves = [(0, -1.0, turn, length, 1.0, {0: 0}) for turn in (-1, 0, 1)]
        # where the straight train fits behind the car (toward the robot, along theta): the
        # only places a pull may start or go (a driver pulls a straight train)
        fits = np.ones((m, k_n), dtype=bool)
        for reach in np.arange(h, train_length + 1e-9, h):
            i2 = ii[:, None] + np.rint(reach * np.sin(th0) / h).astype(int)[None, :]
            j2 = jj[:, None] + np.rint(reach * np.cos(th0) / h).astype(int)[None, :]
            inside = (i2 >= 0) & (i2 < ny) & (j2 >= 0) & (j2 < nx)
            fits &= inside & free[np.clip(i2, 0, ny - 1), np.clip(j2, 0, nx - 1)]
        cell_x, cell_y = x0 + h * jj, y0 + h * ii  # the cells' centres [m]
        for gear, sigma, turn, run, factor, after in moves:
            s_pts = np.linspace(0.0, run, max(5, int(math.ceil(run / h)) + 1))[1:]
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
            # each heading in turn over every cell (m, samples): the same tests as over all
            # (cell, heading) pairs at once, in a tenth of the memory
            di = np.rint(py / h).astype(int)  # (K, samples)
            dj = np.rint(px / h).astype(int)
            offsets = None if band is None else _band_offsets(band, px, py, th0, turn, radius,
                                                               sigma, s_pts)
            ok = np.zeros((m, k_n), dtype=bool)
            for k in range(k_n):
                i2 = ii[:, None] + di[k]
                j2 = jj[:, None] + dj[k]
                good = ((i2 >= 0) & (i2 < ny) & (j2 >= 0) & (j2 < nx)).all(axis=1)
                good &= free[np.clip(i2, 0, ny - 1), np.clip(j2, 0, nx - 1)].all(axis=1)
                if offsets is not None:
                    _band_clear(band[0], band[1], offsets, k, cell_x, cell_y, good)
                ok[:, k] = good
            ok = ok.reshape(-1)  # cell-major like cell and kk
            i2c = np.clip(ii[cell[ok]] + di[kk[ok], -1], 0, ny - 1)  # the moves' ends
            j2c = np.clip(jj[cell[ok]] + dj[kk[ok], -1], 0, nx - 1)
            src = self._state(cell[ok], kk[ok], 0) // GEARS
            dst_cell = index[i2c, j2c]
            k_end = (kk[ok] + turn * step) % k_n
            cost = run * factor + turn_weight * abs(turn) * dth * step
            straight = fits[dst_cell, k_end]
            for g_prev, g_next in after.items():
                keep = straight if g_next in (1, 2) else slice(None)
                rows.append((src * GEARS + g_prev)[keep])
                cols.append(self._state(dst_cell, k_end, g_next)[keep])
                cusp = (g_prev == 1) != (gear == 1)
                weights.append(np.full(rows[-1].size, cost + (cusp_cost if cusp else 0.0)))
        n_states = m * k_n * GEARS
        r = np.concatenate(rows)
        c = np.concatenate(cols)
        w = np.concatenate(weights)
        # reversed moves: the distance from the goal on the transposed graph is the cost to it
        graph = csr_matrix((w, (c, r)), shape=(n_states, n_states))
        # the goal: the cells around it (the rounding of the moves lands on any of them) in
        # the goal's heading bin and its two neighbours, any gear
        gu, gv = (goal[0] - x0) / h, (goal[1] - y0) / h
        kg = self._bin(goal[2])
        sources = []
        for gi in (int(math.floor(gv)), int(math.floor(gv)) + 1):
            for gj in (int(math.floor(gu)), int(math.floor(gu)) + 1):
                if 0 <= gi < ny and 0 <= gj < nx and free[gi, gj]:
                    sources += [self._state(index[gi, gj], (kg + dk) % k_n, g)
                                for dk in (-1, 0, 1) for g in ((0,) if push_only
                                                               else range(GEARS))]
        self.cost = np.full((ny, nx, k_n, GEARS), np.inf)
        self._next = None
        if sources and push_only:
            # the predecessors on the reversed graph are each state's next state toward the goal
            dist, self._next, _ = dijkstra(graph, directed=True, indices=sources,
                                           min_only=True, return_predecessors=True)
            self.cost[ii, jj] = dist.reshape(m, k_n, GEARS)
        elif sources:
            dist = dijkstra(graph, directed=True, indices=sources, min_only=True)
            self.cost[ii, jj] = dist.reshape(m, k_n, GEARS)
        self._index = index
        self._cells = (ii, jj)
        self._goal = (float(goal[0]), float(goal[1]))

    def push_path(self, pose) -> np.ndarray | None:
        """The car's cheapest pushing-only way (built with ``push_only``) from ``pose`` (chain
        convention) to the goal: (m, 2) positions [m] of its moves' ends, from ``pose`` to the
        goal; None where it has none."""
        if self._next is None:
            return None
        ny, nx = self.free.shape
        k = self._bin(pose[2])
        u, v = (pose[0] - self.x0) / self.h, (pose[1] - self.y0) / self.h
        best, state = math.inf, None
        for i in (int(math.floor(v)), int(math.floor(v)) + 1):
            for j in (int(math.floor(u)), int(math.floor(u)) + 1):
                if 0 <= i < ny and 0 <= j < nx and self._index[i, j] >= 0:
                    if self.cost[i, j, k, 0] < best:
                        best, state = self.cost[i, j, k, 0], self._state(self._index[i, j], k, 0)
        if state is None:
            return None
        ii, jj = self._cells
        out = [(float(pose[0]), float(pose[1]))]
        while state >= 0:
            cell = state // (self.k * GEARS)
            out.append((self.x0 + self.h * jj[cell], self.y0 + self.h * ii[cell]))
            state = int(self._next[state])
        out.append(self._goal)
        return np.array(out)

    def _state(self, cell, k: int, gear: int):
        return (cell * self.k + k) * GEARS + gear

    def _cell(self, x: float, y: float) -> tuple[int, int]:
        return (int(round((y - self.y0) / self.h)), int(round((x - self.x0) / self.h)))

    def _bin(self, theta: float) -> int:
        return int(round(theta / (2.0 * math.pi / self.k))) % self.k

    def __call__(self, pose, direction: int = 0, straight: bool = True) -> float:
        """Cost [m] from ``pose`` (chain convention) with the last motion's ``direction``
        (PUSH +1, PULL -1, 0 none) to the goal; inf off the grid or where unreachable.
        ``straight``: whether the chain is straight enough to pull (after a push)."""
        u, v = (pose[0] - self.x0) / self.h, (pose[1] - self.y0) / self.h
        ny, nx = self.free.shape
        i0, j0 = int(math.floor(v)), int(math.floor(u))
        if not (0 <= i0 < ny - 1 and 0 <= j0 < nx - 1):
            return math.inf
        k = self._bin(pose[2])
        push = [0, 2] if straight else [0]
        gears = {1: push, -1: [1]}.get(direction, [0, 1, 2] if straight else [0, 1])
        # the best of the four surrounding cells, plus the way to its centre
        best = math.inf
        for i in (i0, i0 + 1):
            for j in (j0, j0 + 1):
                value = float(self.cost[i, j, k, gears].min())
                best = min(best, value + self.h * math.hypot(u - j, v - i))
        if best == math.inf and not straight:
            # no room for the car's straightening run: the chain may straighten in less
            return self(pose, direction, True)
        return best


def _band_offsets(band: tuple, px: np.ndarray, py: np.ndarray, th0: np.ndarray, turn: int,
                  radius: float, sigma: float, s_pts: np.ndarray) -> list[tuple]:
    """Offsets [m] from the car of the points a move must keep clear, per heading bin
    (K, samples) each: the move's own samples (``px``, ``py``) and, on an arc, the same samples
    on the arcs of radii ``band[2]`` [m] round its centre (the ring the turning train sweeps)."""
    radii = band[2]
    offsets = [(px, py)]
    if turn != 0:
        kap = turn / radius
        th = th0[:, None] + kap * s_pts[None, :]
        vx, vy = sigma * np.sin(th) / kap, -sigma * np.cos(th) / kap  # centre -> car
        cx, cy = -vx[:, :1], -vy[:, :1]
        offsets += [(cx + vx * r * abs(kap), cy + vy * r * abs(kap)) for r in radii
                    if abs(r - radius) > 0.01]
    return offsets


def _band_clear(field, clearance: float, offsets: list[tuple], k: int, x: np.ndarray,
                y: np.ndarray, good: np.ndarray) -> None:
    """Clear ``good`` (m,) where the car at (x, y) (m,) [m] in heading bin ``k`` misses
    ``clearance`` [m] on the distance field at one of its move's points (``offsets``, see
    :func:`_band_offsets`). Points of cells already refused are not looked up."""
    for qx, qy in offsets:
        sel = np.flatnonzero(good)
        if sel.size == 0:
            return
        d = field.at(x[sel, None] + qx[k][None, :], y[sel, None] + qy[k][None, :])
        good[sel] = (d >= clearance).all(axis=1)


GEARS = 3
"""Gears of the :class:`CarGrid`'s states: pushing, pulling, pushed straight."""


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
