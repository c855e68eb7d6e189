"""The closed-loop propagator: the train under its controller along a piece of reference.

The whole-train planner (:mod:`~pushtrain.planner.lattice`) grows its search by appending line,
arc and Reeds-Shepp pieces to the last trailer's reference and asking what the *train* does
when the co-simulation's controller tracks them. This module answers that, resumably:

State (:class:`pushtrain.core.engine.LoopState`, the engine's own)
    The control instant ``k`` (time ``k * step``), the kinematic chain
    ``z = (x0, y0, theta_0..theta_n)`` and the controller's memory (the previous command and
    its time, for the rate limits). The state is taken at an instant *before* its command.
Reference cursor (:class:`Cursor`)
    Where the reference stands: the last trailer's reference pose at time ``t`` and the
    direction of its last motion (0 before any).
Rollout (:meth:`Propagator.rollout`, an :class:`EdgeRun`: the engine's
:class:`~pushtrain.core.engine.EngineRun` and the planner's verdict on it)
    ``Reference.from_segments(cursor pose, segments, speed, cusp_dwell, t0)`` with
    ``t0 = cursor.t`` plus one cusp dwell if the first segment turns the cursor's direction
    (the reference then rests at the cursor before ``t0``, as a longer reference would during
    its dwell), tracked by the co-simulation's control law on the kinematic chain with the one
    closed-loop engine, :class:`pushtrain.core.engine.ClosedLoopEngine` (``core/csrc``: the loop
    :func:`pushtrain.core.engine.simulate` runs, RK4 of the towed chain under the held command,
    step ``tracker.step``), from the state's instant up to the first
    instant at or after the reference's end. The commands up to there depend only on these
    segments, so appending pushes is exact: a rollout continued piece by piece gives the run of
    the whole reference. Pulls are not: the robot's pulling reference (the pull guide) is
    computed backward from the end of the whole pulling run, so the search rolls a growing pull
    out again from where the run began (see :mod:`~pushtrain.planner.lattice`).
Checks
    The engine checks every state it visits (see :class:`Propagator`): every body's clearance
    against the distance field, the joint limit and self-collision; a rollout stops at its first
    failure.
Goal
    With ``goal`` given, the run goes on past the reference's end at rest until the last
    trailer is within ``tracker.goal_tolerance`` of it (the co-simulation's goal test: the first
    control instant at or after the end within the tolerance) or ``tracker.settle_time`` has
    passed.

About 2 us per simulated step with its checks for three trailers
(``benchmarks/bench_rollout.py`` times the engine alone). The engine needs a C compiler, as the
FMUs do (compiled on first use). Units: SI, radians.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.engine import Checks, ClosedLoopEngine, EngineRun, LoopState, join_runs
from pushtrain.core.kinematics import ChainGeometry, body_positions
from pushtrain.core.reference import Reference
from pushtrain.core.segment import PULL, PUSH, Segment
from pushtrain.facility.distance_field import DistanceField

from .config import TrackerConfig
from .footprint import FIELD_TOLERANCE, BodySamples, disc_cover, first_failure
from .train import Train

__all__ = ["Cursor", "EdgeRun", "Propagator", "last_pose"]


@dataclass(frozen=True)
class Cursor:
    """The reference's end so far: the last trailer's pose (x, y, theta) [m, m, rad] at time
    ``t`` [s] and the direction of its last motion (PUSH, PULL or 0 before any)."""

    x: float
    y: float
    theta: float
    t: float
    direction: int = 0

    @property
    def pose(self) -> tuple:
        return (self.x, self.y, self.theta)


@dataclass
class EdgeRun:
    """What :meth:`Propagator.rollout` simulated: the engine's run and the planner's verdict.

    Attributes
    ----------
    run : EngineRun
        The engine's run from the rollout's start state (its pieces joined,
        :func:`~pushtrain.core.engine.join_runs`): ``states`` (K + 1, 3 + n) the first the
        start state's, ``commands``, ``reference`` and ``direction`` (K rows), ``end`` the
        :class:`~pushtrain.core.engine.LoopState` reached: at the first instant at or after the
        reference's end (with a goal: where it was reached, or the end of the settling); at a
        failure the last state simulated.
    cursor : Cursor
        The reference's end.
    failure : dict or None
        The first failure: ``kind`` (``"collision"``, ``"joint_limit"``, ``"self_collision"``,
        ``"non_finite"``, ``"control"`` from the engine's checks; ``"pull_rule"``,
        ``"budget"``, ``"deadline"``, ``"goal_missed"``), the instant ``k``, its time ``t`` [s],
        ``body`` and where (``x``, ``y`` [m]), with the numbers of its kind (``distance`` and
        ``margin``, ``phi``, ``other``, ``heading_error``, ...).
    goal_error : (float, float) or None
        Distance [m] and |heading error| [rad] of the last trailer to the goal at the end.
    from_start : bool
        The run starts at the search's start state (it is the whole path's run).
    """

    run: EngineRun
    cursor: Cursor
    failure: dict | None = None
    goal_error: tuple | None = None
    from_start: bool = False

    @property
    def ok(self) -> bool:
        """No failure (and, with a goal, the goal reached)."""
        return self.failure is None

    @property
    def state(self) -> LoopState:
        """Where the run ended (``run.end``)."""
        return self.run.end

    @property
    def steps(self) -> int:
        """Control steps simulated (the unit of the planner's work budget)."""
        return self.run.states.shape[0] - 1


def _max_abs_phi(z: Sequence[float]) -> float:
    """The largest |phi_i| [rad] of a train state ``z`` (plain floats)."""
    return max(abs(math.remainder(z[i] - z[i + 1], 2.0 * math.pi)) for i in range(2, len(z) - 1))


def last_pose(z: Sequence[float], geometry: ChainGeometry) -> tuple:
    """The last trailer's pose (x, y, theta) [m, m, rad] from a train state ``z`` (3 + n)
    (:func:`~pushtrain.core.kinematics.body_positions`), as plain floats."""
    x, y = body_positions(z[0], z[1], z[2:], geometry)
    return float(x[-1]), float(y[-1]), float(z[-1])


class Propagator:
    """Closed-loop rollouts of the train along reference pieces (see the module docstring) on
    the compiled engine (:class:`pushtrain.core.engine.ClosedLoopEngine`).

    Parameters
    ----------
    train : Train
        The plant (geometry, footprints, joint limit).
    controller : ControllerConfig
        The co-simulation's controller.
    tracker : TrackerConfig
        Reference speed, cusp dwell, control step, settle time and goal tolerance.
    field : DistanceField
        The map's signed distance field.
    samples : BodySamples
        Every body's sample points and thresholds
        (:func:`~pushtrain.planner.footprint.body_samples`).
    phi_limit : float
        Largest |phi_i| [rad] allowed along a rollout.
    goal_phi : float or None
        The goal also needs every |phi_i| <= ``goal_phi`` [rad] (a straight train); None: any
        chain.
    cover : float
        Cell size [m] of each body's disc cover (:func:`~pushtrain.planner.footprint.disc_cover`):
        a body whose discs all keep its clearance plus their radius is clear at that state
        whatever its sample points say (both tests are conservative; either proves it).

    The engine checks every state it visits: the joint limit, self-collision and the walls, the
    walls in two tiers at each state:

    coarse
        Each body's rectangle covered by a few discs (cells of at most ``cover`` metres, about
        0.2 m radius for a 0.8 m x 0.6 m trailer); a body keeps its clearance, inside included,
        if every disc centre keeps the clearance plus the radius. Six lookups per trailer
        instead of a hundred: a train in a corridor wider than itself passes it.
    fine
        Only for a body that failed the coarse test at that state: its perimeter points
        (:attr:`BodySamples.threshold` of the perimeter as the body's margin) decide. The
        compiled loop has no per-point thresholds, so the interior points of
        :func:`~pushtrain.planner.footprint.body_samples` (an obstacle wholly inside a body,
        smaller than it) are left to the exact test of the final path.

    The pull rule, the goal test, ``max_steps`` and the deadline are applied between runs of the
    loop (a run stops at every pulling run's first instant, and runs ``chunk`` states at most).
    """

    def __init__(self, train: Train, controller: ControllerConfig, tracker: TrackerConfig,
                 field: DistanceField, samples: BodySamples, phi_limit: float,
                 goal_phi: float | None = None, cover: float = 0.3):
        self.train = train
        self.covers = []
        for i, body in enumerate(train.bodies):
            centres, radius = disc_cover(body, cover)
            self.covers.append((centres, float(samples.margins[i]) + radius + FIELD_TOLERANCE))
        self.controller = controller
        self.tracker = tracker
        self.field = field
        self.samples = samples
        self.phi_limit = float(phi_limit)
        self.goal_phi = None if goal_phi is None else float(goal_phi)
        self.step = float(tracker.step)
        self.steps = 0
        """Control steps simulated by this propagator so far (all rollouts)."""
        points, margins = [], []
        for i in range(train.n + 1):
            sel = samples.body == i
            perimeter = sel & (samples.threshold == samples.threshold[sel].min())
            points.append(np.column_stack([samples.u[perimeter], samples.v[perimeter]]))
            margins.append(float(samples.threshold[perimeter][0]))
        discs = [c for c, _ in self.covers]
        disc_margins = [m for _, m in self.covers]
        rectangles = [[b.offset, 0.0, 0.5 * b.length, 0.5 * b.width] for b in train.bodies]
        grid = {"sdf": field.values, "origin": (field.x0, field.y0),
                "resolution": field.resolution, "phi_max": self.phi_limit,
                "rectangles": rectangles}
        self.checks = Checks(train.n, points=discs, margins=disc_margins, fine_points=points,
                             fine_margins=margins, **grid)
        self.loop = ClosedLoopEngine(train.geometry, controller, self.step, 0.0, self.checks)

    # ------------------------------------------------------------------ states
    def initial_state(self, start: Sequence[float], headings: Sequence[float]) -> LoopState:
        """The state at t = 0: the last trailer at ``start`` with ``headings`` (n+1,) [rad], at
        rest, the rate limits starting from rest one step before (as the co-simulation)."""
        return self.loop.start(start, headings)

    def last_pose(self, state: LoopState) -> tuple:
        """The last trailer's pose (x, y, theta) [m, m, rad] in ``state``."""
        return last_pose(state.z, self.train.geometry)

    def check(self, z: np.ndarray):
        """:func:`~pushtrain.planner.footprint.first_failure` of states ``z`` (K, 3 + n)."""
        return first_failure(self.train, self.field, self.samples, z, self.phi_limit,
                             covers=self.covers)

    # ------------------------------------------------------------------ rollout
    def reference(self, cursor: Cursor, segments: Sequence[Segment]) -> Reference:
        """The reference of ``segments`` continued from ``cursor`` (a dwell first if they turn
        the cursor's direction)."""
        dwell = float(self.tracker.cusp_dwell)
        turn = cursor.direction in (PUSH, PULL) and segments[0].direction != cursor.direction
        t0 = cursor.t + dwell if turn and dwell > 0.0 else cursor.t
        return Reference.from_segments(cursor.pose, list(segments), self.tracker.speed, dwell, t0)

    def rollout(self, state: LoopState, cursor: Cursor, segments: Sequence[Segment],
                goal: Sequence[float] | None = None, pull_phi: float | None = None,
                max_steps: int | None = None, deadline: float | None = None,
                chunk: int = 4000) -> EdgeRun:
        """Track ``segments`` from ``state`` with the reference continued from ``cursor``.

        Parameters
        ----------
        state, cursor : LoopState, Cursor
        segments : sequence of Segment
        goal : (x, y, theta) or None
            Go on at rest until the last trailer is within the goal tolerance of it.
        pull_phi : float or None
            The pull rule: every pulling run of the reference must start (at the first instant
            at or after its start) with every |phi_i| <= ``pull_phi`` [rad]; else the rollout
            fails with kind ``"pull_rule"``.
        max_steps : int or None
            Stop (failure kind ``"budget"``) after this many steps.
        deadline : float or None
            ``time.perf_counter()`` value at which to stop (failure kind ``"deadline"``).
        chunk : int
            Most states one call of the engine runs (the deadline is looked at in between).
        """
        ref = self.reference(cursor, segments)
        loop, step, geometry = self.loop, self.step, self.train.geometry
        t_end = ref.t_end
        end = ref.sample_at(t_end)
        new_cursor = Cursor(end.x, end.y, end.theta, t_end, segments[-1].direction)
        k_end = max(state.k, loop.instant_at(t_end))
        k_stop = k_end
        if goal is not None:
            k_stop = max(k_end, loop.instant_at(t_end + self.tracker.settle_time))
            tol = self.tracker.goal_tolerance or (math.inf, math.inf)
        pull_starts = ([k for k in (loop.instant_at(a) for a, _ in ref.pull_intervals())
                        if k >= state.k] if pull_phi is not None else [])
        limit = math.inf if max_steps is None else state.k + int(max_steps)
        here = state
        pieces, failure = [], None
        reached, goal_error = False, None
        while True:
            k = here.k
            if pull_starts and k == pull_starts[0]:
                pull_starts.pop(0)
                worst = _max_abs_phi(here.z)
                if worst > pull_phi:
                    x, y, _ = last_pose(here.z, geometry)
                    failure = {"kind": "pull_rule", "k": k, "body": self.train.n, "x": x,
                               "y": y, "phi": worst}
                    break
            if goal is not None and k >= k_end:
                x, y, th = last_pose(here.z, geometry)
                dist = math.hypot(x - goal[0], y - goal[1])
                head = abs(math.remainder(th - goal[2], 2.0 * math.pi))
                goal_error = (dist, head)
                if dist <= tol[0] and head <= tol[1] and (
                        self.goal_phi is None or _max_abs_phi(here.z) <= self.goal_phi):
                    reached = True
                    break
            if k >= k_stop:
                break
            if k >= limit or (deadline is not None and time.perf_counter() >= deadline):
                x, y, _ = last_pose(here.z, geometry)
                failure = {"kind": "budget" if k >= limit else "deadline", "k": k,
                           "body": self.train.n, "x": x, "y": y}
                break
            # run to the next instant where something must be looked at
            target = min(k_stop, k + chunk, limit)
            if k < k_end:
                target = min(target, k_end)
            else:
                target = min(target, k + 1)  # settling: the goal test at every instant
            if pull_starts:
                target = min(target, pull_starts[0])
            run = loop.run(ref, here, target, record=True)
            pieces.append(run)
            here = run.end
            if run.violation is not None:
                failure = _failure_of(run.violation, self.samples.margins)
                break
        self.steps += here.k - state.k
        if pieces:
            run = join_runs(pieces)
        else:
            run = EngineRun(np.array([here.k * step]), np.array([here.z]), np.zeros((0, 2)),
                            np.zeros((0, 3)), np.zeros(0, dtype=int), here, None)
        if failure is None and goal is not None and not reached:
            x, y, _ = last_pose(here.z, geometry)
            failure = {"kind": "goal_missed", "k": here.k, "t": here.k * step,
                       "body": self.train.n, "x": x, "y": y, "distance": goal_error[0],
                       "heading_error": goal_error[1], "max_abs_phi": _max_abs_phi(here.z)}
        if failure is not None:
            failure.setdefault("t", failure["k"] * step)
        return EdgeRun(run, new_cursor, failure, goal_error)


def _failure_of(violation, margins) -> dict:
    """A :class:`~pushtrain.core.engine.Violation` as an :attr:`EdgeRun.failure`."""
    base = {"k": int(violation.step), "t": float(violation.t), "body": int(violation.body),
            "x": float(violation.x), "y": float(violation.y)}
    if violation.reason == "footprint":
        return {"kind": "collision", **base, "distance": float(violation.value),
                "margin": float(margins[violation.body])}
    if violation.reason == "joint_limit":
        return {"kind": "joint_limit", **base, "phi": float(violation.value)}
    if violation.reason == "self_collision":
        return {"kind": "self_collision", **base, "other": violation.other}
    return {"kind": violation.reason, **base}
