"""Closed-loop lattice search: hybrid A* whose nodes are the train under its controller.

Why this design (and not the last trailer alone, nor closed-loop RRT)
    Planning the last trailer and checking the train afterwards fails where the followers
    decide (a 0.9 m bay, a 1.3 m L with five trailers) and where the pull must wait for a
    straight chain (a three-point turn). Here every node *is* a state the train can be in,
    reached by the co-simulation's own controller, so what the search keeps the train can do.
    Two published approaches search such states: closed-loop RRT (Evestedt et al., IROS 2016:
    random references tracked in closed loop) and lattice planners (Ljungqvist et al., JFR
    2019: a fixed set of short motions, searched with A*). A lattice search is deterministic
    (a seed never changes the plan, budgets count expansions, not seconds), finds the
    manoeuvres with few cusps that its cost asks for (turning and cusps are priced, so straight
    aisles stay straight), and reuses expensive rollouts through duplicate pruning; RRT's
    random references give the S-bends that drivers do not make. The search is hybrid A*
    (continuous poses, pruning on a grid) rather than a strict lattice because the reference
    after a closed-loop rollout is exactly where it was put, while the train is where the
    controller brought it: a continuous state.

Node
    The reference's end (:class:`~pushtrain.planner.propagate.Cursor`: the last trailer's
    reference pose, its time and the direction of the last motion) and the train's state there
    (the engine's :class:`~pushtrain.core.engine.LoopState`: robot pose, every heading, the
    controller's rate-limit memory, the control instant).
Edges
    A primitive of the last trailer's reference (a line or an arc of curvature ``k * kappa``
    for k in ``curvatures``, ``step_length`` metres, pushing or pulling) appended to the
    reference and tracked in closed loop by the co-simulation's controller
    (:class:`~pushtrain.planner.propagate.Propagator`), every body checked against the distance
    field with its clearance, every joint against the limit, non-neighbouring bodies against
    each other. A pull that continues a pull is rolled out again from where the pulling run
    began: the robot's pulling reference is computed backward from the run's end
    (:class:`~pushtrain.core.pulling.PullGuide`), so a longer run changes its beginning too.
    Pushes are exactly resumable.
Pulls a driver would make
    A pulling run may start only where every |phi_i| <= ``pull_phi`` (the chain nearly
    straight, so the robot can lead it), checked at the run's first control instant. The search
    therefore pushes on until the chain is straight and chooses the cusp there.
Cost
    Travelled length (pulls weighted by ``pull_factor``), plus ``turn_weight`` times the
    heading turned (the integral of |curvature|), ``change_weight`` per change of curvature and
    ``cusp_cost`` per direction change: straight stays straight, and turns are few.
Heuristic
    The larger of the Reeds-Shepp length to the goal and the obstacle-aware distance of the map
    (:class:`~pushtrain.planner.heuristic.Heuristic`), times ``weight`` (>= 1: a faster, less
    optimal search).
Goal
    Reached only by a connection from a node (:mod:`~pushtrain.planner.goal_connections`):
    the driver's corner (straight, arc, straight), the same after a straightening push, a
    pull-back where the route comes in across the goal (pushed round into the far branch of
    the junction until the train is straight, then pulled back onto the goal), and
    Reeds-Shepp paths (radius ``turning radius * f`` for f in ``analytic_radii``). Each is
    first checked cheaply (the last trailer's own footprint along it), then tracked in closed
    loop until the simulated last trailer rests within the goal tolerance (the co-simulation's
    goal test).
Duplicates
    Nodes fall into cells of the reference pose (``grid_xy``, ``grid_theta``), the direction of
    the last motion and the chain's bend (robot heading minus last trailer heading, in bins of
    ``grid_bend``); a cell keeps its cheapest node.

The search counts its work in simulated control steps; it stops when ``budget_steps`` are spent
(the result depends only on that count) or at the wall-clock ``deadline`` (the result then says
it was cut short).
"""

from __future__ import annotations

import heapq
import itertools
import logging
import math
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from pushtrain.core.engine import LoopState
from pushtrain.core.field import poses_clear
from pushtrain.core.kinematics import body_positions
from pushtrain.core.segment import PULL, PUSH, Segment

from .connect import corner_segments, sample_reference
from .goal_connections import GoalConnections
from .heuristic import Heuristic
from .lattice_settings import LatticeSettings, segments_cost
from .propagate import Cursor, EdgeRun, Propagator
from .reeds_shepp import rs_segments
from .route import Route
from .train import Train

__all__ = ["Node", "Search", "Solution"]

log = logging.getLogger(__name__)


@dataclass(eq=False)
class Node:
    """One state of the search (see the module docstring)."""

    state: LoopState
    cursor: Cursor
    g: float
    h: float
    parent: Node | None = None
    segments: tuple = ()
    run_root: Node | None = None
    run_segments: tuple = ()
    trace: np.ndarray | None = None
    depth: int = 0

    @property
    def run_length(self) -> float:
        return float(sum(s.length for s in self.run_segments))

    def path_segments(self) -> list[Segment]:
        """The reference's segments from the start to this node."""
        out, node = [], self
        while node is not None:
            out[:0] = node.segments
            node = node.parent
        return out

    def curvature(self) -> float | None:
        return self.segments[-1].curvature if self.segments else None


@dataclass
class Solution:
    """A path to the goal found by the search: the reference's segments from the start, its
    cost, the node it leaves from and the closed loop of its last piece."""

    segments: list
    cost: float
    node: Node
    rollout: EdgeRun
    expansions: int
    steps: int


@dataclass
class Stats:
    """What the search did and what stopped its motions (for the diagnostics)."""

    expansions: int = 0
    rollouts: int = 0
    analytic_tries: int = 0
    analytic_closed_loop: int = 0
    failures: Counter = field(default_factory=Counter)
    bodies: Counter = field(default_factory=Counter)
    points: list = field(default_factory=list)
    cut: str | None = None
    car_built_at: int | None = None
    steps: Counter = field(default_factory=Counter)

    def record(self, failure: dict) -> None:
        kind = failure["kind"]
        self.failures[kind] += 1
        if kind in ("collision", "self_collision"):
            self.bodies[failure["body"]] += 1
        if len(self.points) < 400:
            self.points.append({k: failure[k] for k in ("kind", "x", "y", "body")
                                if k in failure})


class Search:
    """Hybrid A* over closed-loop train states (see the module docstring).

    Parameters
    ----------
    train : Train
    propagator : Propagator
    heuristic : Heuristic
    start : LoopState
    start_cursor : Cursor
    goal : (x, y, theta)
    settings : LatticeSettings
    route : callable or None
        Returns the route through the building (:mod:`~pushtrain.planner.route`), or None;
        called once, when the search first expands a node (a goal its start connects to
        needs none). Pushes along it are added to each node's motions.
    """

    def __init__(self, train: Train, propagator: Propagator, heuristic: Heuristic,
                 start: LoopState, start_cursor: Cursor, goal, settings: LatticeSettings,
                 route: Callable[[], Route | None] | None = None):
        self.train = train
        self._route_of = route
        self._route: Route | None = None
        self.prop = propagator
        self.heuristic = heuristic
        self.goal = tuple(float(a) for a in goal)
        # the longest straight a connection may have [m]: the map's diagonal (a near U-turn's
        # corner lies far outside the map, and its reference took gigabytes to check)
        ny, nx = propagator.field.values.shape
        self.reach = math.hypot(nx, ny) * propagator.field.resolution
        self.s = settings
        self.kappa = 1.0 / settings.radius
        self.stats = Stats()
        self._counter = itertools.count()
        self._open: list = []
        self._best: dict = {}
        self.nodes: list[Node] = []
        self._last_analytic = -10**9
        self._pending: Node | None = None
        # the last trailer's outline points and their thresholds, and its reach (a pose whose
        # axle midpoint keeps it is clear whatever its points say): reference_clear's body
        smp = propagator.samples
        sel = smp.body == train.n
        self._last_points = tuple(np.ascontiguousarray(a[sel], dtype=float)
                                  for a in (smp.u, smp.v, smp.threshold))
        self._last_reach = float(smp.slack[train.n])
        self.connections = GoalConnections(train, propagator, self.goal, settings, self.reach,
                                           lambda: self.route, self.reference_clear,
                                           start=start_cursor.pose)
        root = Node(start, start_cursor, 0.0, heuristic(start_cursor.pose))
        self.root = root
        self.closest = root
        self._push(root)

    @property
    def route(self) -> Route | None:
        """The route through the building (built on first use), or None."""
        if self._route_of is not None:
            self._route, self._route_of = self._route_of(), None
        return self._route

    # ------------------------------------------------------------------ bookkeeping
    def _key(self, node: Node) -> tuple:
        c = node.cursor
        s = self.s
        bend = math.remainder(node.state.z[2] - node.state.z[-1], 2.0 * math.pi)
        return (round(c.x / s.grid_xy), round(c.y / s.grid_xy),
                round(math.remainder(c.theta, 2.0 * math.pi) / s.grid_theta)
                % round(2.0 * math.pi / s.grid_theta),
                c.direction, round(bend / s.grid_bend))

    def _push(self, node: Node) -> bool:
        if node.h == math.inf:
            return False
        key = self._key(node)
        old = self._best.get(key)
        if old is not None and old <= node.g + 1e-9:
            return False
        self._best[key] = node.g
        f = node.g + self.s.weight * node.h
        heapq.heappush(self._open, (f, next(self._counter), node))
        self.nodes.append(node)
        if node.h < self.closest.h:
            self.closest = node
        return True

    def _spent(self) -> str | None:
        if self.prop.steps >= self.s.budget_steps:
            return "budget"
        if time.perf_counter() >= self.s.deadline:
            return "deadline"
        return None

    # ------------------------------------------------------------------ the loop
    def next_solution(self, rejected=None) -> Solution | None:
        """Search on until the next path to the goal; None when the open list is empty or
        the budget is spent (``stats.cut`` says which)."""
        if self._pending is not None:
            # the node whose connection to the goal was the last solution: its own motions
            node, self._pending = self._pending, None
            self._expand_all(node)
        while self._open:
            cut = self._spent()
            if cut is not None:
                self.stats.cut = cut
                return None
            if (self.heuristic.car is None and self.stats.expansions >= self.s.car_after
                    and self._can_build_car()):
                self._rebuild_heuristic()
            _, _, node = heapq.heappop(self._open)
            if self._best.get(self._key(node), math.inf) < node.g - 1e-9:
                continue  # a cheaper node took its cell after it was queued
            self.stats.expansions += 1
            solution = self._analytic(node)
            if solution is not None:
                self._pending = node
                return solution
            self._expand_all(node)
        if self._spent() is not None:
            self.stats.cut = self._spent()
        return None

    def _expand_all(self, node: Node) -> None:
        """Queue every child of ``node`` that its motions reach. From a start in a tight spot
        every full-length motion may hit a wall: then shorter ones (``inch_fractions``, a
        driver's inching out) are tried before the search gives up."""
        motions = itertools.chain(self._follow(node), self._primitives(node))
        inching = self.s.inch_fractions if node is self.root else ()
        for fraction in (None, *inching):
            if fraction is not None:
                motions = self._primitives(node, fraction)
            moved = False
            for segments in motions:
                if self._spent() is not None:
                    return
                child = self._expand(node, segments)
                if child is not None:
                    moved = True
                    self._push(child)
            if moved:
                return

    def _can_build_car(self) -> bool:
        """Whether the car heuristic is configured and its build (about 2 us per state of
        CPU, three times that allowed for a loaded machine) fits before the deadline."""
        estimate = self.heuristic.car_states() * 6e-6
        return estimate > 0.0 and time.perf_counter() + estimate < self.s.deadline

    def _rebuild_heuristic(self) -> None:
        """Switch to the heuristic with the :class:`~pushtrain.planner.heuristic.CarGrid`
        (the search found no path in ``car_after`` expansions: it may need to turn around or
        to go the long way) and re-queue the open nodes with it."""
        self.heuristic.build_car()
        self.stats.car_built_at = self.stats.expansions
        queued = [item[2] for item in self._open]
        self._open = []
        for node in queued:
            node.h = self._h(node.cursor, node.state)
            if node.h < math.inf:
                heapq.heappush(self._open, (node.g + self.s.weight * node.h,
                                            next(self._counter), node))
        log.debug("car heuristic built after %d expansions", self.stats.expansions)

    def _h(self, cursor: Cursor, state: LoopState) -> float:
        """The heuristic of a node: its reference pose, its last motion's direction and
        whether its chain is straight enough to pull."""
        straight = bool(np.abs(state.phi).max() <= self.s.pull_phi)
        return self.heuristic(cursor.pose, cursor.direction, straight)

    # ------------------------------------------------------------------ edges
    def _primitives(self, node: Node, fraction: float = 1.0):
        """The motions of ``node``: lines and arcs pushing and pulling (``fraction`` of their
        usual lengths; the long straight push only at full length)."""
        s = self.s
        for direction in (PUSH, PULL):
            if direction == PULL:
                if node.cursor.direction == PULL:
                    if node.run_length + s.pull_length > s.max_pull_run + 1e-9:
                        continue
                elif np.abs(node.state.phi).max() > s.pull_phi:
                    self.stats.failures["pull_rule"] += 1
                    continue
            length = fraction * (s.pull_length if direction == PULL else s.step_length)
            for k in (s.pull_curvatures if direction == PULL else s.curvatures):
                kappa = k * self.kappa
                kind = "line" if kappa == 0.0 else "arc"
                yield [Segment(kind, length, kappa, direction)]
            if direction == PUSH and fraction == 1.0 and s.long_straight > length:
                yield [Segment("line", s.long_straight, 0.0, PUSH)]

    def _follow(self, node: Node):
        """Pushes along the route: from the node's reference pose to the route's pose
        ``follow_lengths`` metres ahead of the nearest route point (the train pushed along the
        route there), by the driver's corner (straight, arc, straight: the widest arc that fits,
        at least the turning radius) or else a pushing-only Reeds-Shepp curve. A long straight
        or gently curved stretch of corridor then costs one rollout, not a dozen primitives."""
        route, s = self.route, self.s
        if route is None:
            return
        pose = node.cursor.pose
        along, off = route.project(pose[0], pose[1], pose[2] + math.pi)
        if off > s.follow_offset:
            return
        travel_here = route.pose_at(along)[2]
        if abs(math.remainder(pose[2] + math.pi - travel_here, 2.0 * math.pi)) > s.follow_angle:
            return  # not pushed along the route here: the primitives turn it first
        straight = np.abs(node.state.phi).max() <= s.pull_phi
        max_turn = s.follow_turn if straight else s.follow_turn_bent
        for ahead in s.follow_lengths:
            if along + ahead > route.length - 0.5 * ahead:
                return  # the goal is near: the connections take it from here
            if route.turn(along, along + ahead) > max_turn:
                return  # a corner or a junction: the primitives and connections take it
            x, y, travel = route.pose_at(along + ahead)
            target = (x, y, travel + math.pi)
            path = corner_segments(pose, target, PUSH, None, max_radius=4.0 * s.radius,
                                   max_reach=self.reach)
            if path and all(abs(g.curvature) <= self.kappa + 1e-9 for g in path):
                yield path
                continue
            path = rs_segments(pose, target, s.radius)
            if path and all(g.direction == PUSH for g in path) and (
                    sum(g.length for g in path) <= 1.5 * ahead):
                yield path

    def _cost(self, node: Node, segments) -> float:
        return segments_cost(segments, self.s, node.cursor.direction, node.curvature())

    def _roll(self, node: Node, segments, goal=None) -> tuple[EdgeRun, Node | None, tuple]:
        """Roll ``segments`` out after ``node`` (from the start of its pulling run if they
        continue it). Returns (rollout, run root, run segments)."""
        remaining = max(1, self.s.budget_steps - self.prop.steps)
        if segments[0].direction == PULL and node.cursor.direction == PULL:
            root, run = node.run_root, node.run_segments + tuple(segments)
        else:
            root, run = node, tuple(segments)
        # a connection to the goal keeps its commands: from the start it is the whole path's run
        rollout = self.prop.rollout(root.state, root.cursor, run, goal=goal,
                                    pull_phi=self.s.pull_phi, max_steps=remaining,
                                    deadline=self.s.deadline)
        rollout.from_start = root is self.root
        self.stats.rollouts += 1
        self.stats.steps["connections" if goal is not None else "motions"] += rollout.steps
        # the run (for a later continuation) is the tail of pulling segments
        tail = []
        for seg in reversed(run):
            if seg.direction != PULL:
                break
            tail.insert(0, seg)
        if tail and len(tail) < len(run):
            root = None  # a pull run that starts inside these segments: never continued
        return rollout, root, tuple(tail)

    def _expand(self, node: Node, segments: list) -> Node | None:
        if not self._reference_clear(node.cursor, segments):
            self.stats.failures["reference"] += 1
            return None
        rollout, root, run = self._roll(node, segments)
        if not rollout.ok:
            if rollout.failure["kind"] not in ("budget", "deadline"):
                self.stats.record(rollout.failure)
            return None
        h = self._h(rollout.cursor, rollout.state)
        pull = segments[-1].direction == PULL
        child = Node(rollout.state, rollout.cursor, node.g + self._cost(node, segments), h, node,
                     tuple(segments), root if pull else None, run if pull else (),
                     _trace(rollout, self.train.geometry), node.depth + 1)
        return child

    def _reference_clear(self, cursor: Cursor, segments, spacing: float = 0.05) -> bool:
        """The last trailer's own footprint, placed exactly on the reference, keeps its
        clearance along ``segments`` (a cheap necessary condition before a rollout)."""
        return self.reference_clear(cursor.pose, segments, spacing)

    def reference_clear(self, pose, segments, spacing: float = 0.05) -> bool:
        """:meth:`_reference_clear` from a pose (x, y, theta): in C
        (:func:`pushtrain.core.field.poses_clear`; its readable twin is
        ``tests/reference/sweep.py``). Poses whose
        axle midpoint is clear by the body's whole reach are passed without looking at their
        points; the first point that misses ends the test."""
        poses = sample_reference(pose, segments, spacing)
        field = self.prop.field
        u, v, threshold = self._last_points
        return poses_clear(field.values, field.x0, field.y0, field.resolution, poses,
                           self._last_reach, u, v, threshold)

    # ------------------------------------------------------------------ goal
    def _analytic(self, node: Node) -> Solution | None:
        s = self.s
        self.stats.analytic_tries += 1
        due = (self.stats.expansions - self._last_analytic >= s.analytic_every
               or node is self.root)
        attempts = 0
        for kind, segments in self.connections.candidates(node.cursor.pose, node.state.phi,
                                                           kturns=due):
            if kind[0] in ("pullback", "kturn", "approach", "direct") and not due:
                break
            if attempts >= s.analytic_per_node and not due:
                break
            if not segments or not self._reference_clear(node.cursor, segments):
                continue
            attempts += 1
            if kind[0] in ("pullback", "kturn", "approach", "direct"):
                self._last_analytic = self.stats.expansions
            self.stats.analytic_closed_loop += 1
            rollout, _, _ = self._roll(node, segments, goal=self.goal)
            if rollout.ok:
                full = node.path_segments() + list(segments)
                return Solution(full, node.g + self._cost(node, segments), node, rollout,
                                self.stats.expansions, self.prop.steps)
            if rollout.failure["kind"] not in ("budget", "deadline"):
                self.stats.record(rollout.failure)
        return None


def _trace(rollout: EdgeRun, geometry, every: int = 25) -> np.ndarray:
    """The last trailer's positions along a rollout, thinned (for drawing the explored tree)."""
    states = rollout.run.states
    z = states[::every]
    if (states.shape[0] - 1) % every:
        z = np.vstack([z, states[-1:]])
    x, y = body_positions(z[:, 0], z[:, 1], z[:, 2:], geometry)
    return np.column_stack([x[:, -1], y[:, -1]])
