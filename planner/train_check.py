"""Whole-train check: predict the closed loop the co-simulation will run and test every body.

The whole train's motion along the plan is the closed loop the co-simulation will run
(:func:`pushtrain.core.engine.simulate`: the co-simulation's controller on the kinematic chain,
on the closed-loop engine, as :class:`~pushtrain.planner.config.TrackerConfig` says), or the
engine's run the search already made (an :class:`~pushtrain.core.engine.EngineRun`).

Every body's rectangle is tested against the free space shrunk by a margin (shapely,
vectorized) at samples spaced so that no corner of any body travels more than ``resolution``
between two checked samples (steps are subdivided where needed, standing samples are
skipped), and every |phi_i| against the train's ``phi_max`` at every step. The last
trailer's tracking error (distance to the reference sample at the same time, lateral error
and heading error) and its final distance to the goal are reported; missing the goal by more
than ``tracker.goal_tolerance`` is a failure too (the co-simulation would end with
``goal_not_reached``).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import shapely

from pushtrain.core.engine import ClosedLoopEngine, EngineRun, simulate
from pushtrain.core.kinematics import (
    ChainGeometry,
    body_positions,
    joint_angles,
    wrap_angle,
    wrap_scalar,
)
from pushtrain.core.reference import Reference
from pushtrain.core.segment import Segment
from pushtrain.errors import ControllerError, PlanningInputError
from pushtrain.facility.free_space import World

from .config import TrackerConfig
from .footprint import self_overlap
from .path import reference_times
from .train import Train

__all__ = ["TrainCheckResult", "check_train"]

log = logging.getLogger(__name__)


@dataclass
class _Samples:
    """The simulated samples the check looks at, one row each: the engine's control instants
    and the subdivisions :func:`_refine` adds (``control`` False there); ``state`` (3 + n),
    the ``command`` held from the sample on, the last trailer's ``reference`` pose and its
    ``direction``."""

    t: np.ndarray
    state: np.ndarray
    command: np.ndarray
    reference: np.ndarray
    direction: np.ndarray
    control: np.ndarray

    @classmethod
    def of_run(cls, run: EngineRun, reference: Reference) -> _Samples:
        """Every instant of ``run`` (no command at the last one: the run ends there; its
        reference sampled here)."""
        last = reference.sample_at(float(run.t[-1]))
        k = run.t.size
        return cls(run.t, run.states, np.vstack([run.commands, np.zeros((1, 2))]),
                   np.vstack([run.reference, [[last.x, last.y, last.theta]]]),
                   np.concatenate([run.direction, [last.direction]]),
                   np.ones(k, dtype=bool))


def _refine(traj: _Samples, geometry: ChainGeometry, train: Train, resolution: float,
            controller):
    """Subdivide the steps in which some corner moves more than ``resolution`` (RK4 substeps
    under the held command, the closed-loop engine's integrator). Returns (trajectory, x, y,
    corners)."""
    x, y = body_positions(traj.state[:, 0], traj.state[:, 1], traj.state[:, 2:], geometry)
    corners = _corners(train, x, y, traj.state[:, 2:])
    move = np.linalg.norm(np.diff(corners, axis=0), axis=-1).max(axis=(1, 2))
    bad = np.flatnonzero(move > resolution)
    if not bad.size:
        return traj, x, y, corners
    rows = {name: [getattr(traj, name)] for name in ("t", "state", "command", "reference",
                                                     "direction", "control")}
    loop = ClosedLoopEngine(geometry, controller)  # its integrator only (pt_hold)
    for k in bad:
        m = int(math.ceil(move[k] / resolution * 1.05))
        h = (traj.t[k + 1] - traj.t[k]) / m
        v0, w0 = traj.command[k]
        for j, z in enumerate(loop.hold(traj.state[k], v0, w0, h, m - 1), start=1):
            rows["t"].append([traj.t[k] + j * h]), rows["state"].append([z])
            rows["command"].append([traj.command[k]]), rows["reference"].append([traj.reference[k]])
            rows["direction"].append([traj.direction[k]]), rows["control"].append([False])
    merged = {name: np.concatenate([np.asarray(r) for r in parts]) for name, parts in rows.items()}
    order = np.argsort(merged["t"], kind="stable")
    traj = _Samples(**{name: value[order] for name, value in merged.items()})
    x, y = body_positions(traj.state[:, 0], traj.state[:, 1], traj.state[:, 2:], geometry)
    return traj, x, y, _corners(train, x, y, traj.state[:, 2:])


def _corners(train: Train, x, y, headings):
    """Corners (K, n+1, 4, 2) of every body."""
    return np.stack([b.corners(x[:, i], y[:, i], headings[:, i])
                     for i, b in enumerate(train.bodies)], axis=1)


def _thin(move: np.ndarray, resolution: float) -> np.ndarray:
    """Indices of the samples to check: consecutive kept samples are at most ``resolution`` of
    corner travel apart (``move[k]`` <= resolution is the travel from sample k to k + 1)."""
    keep, travelled = [0], 0.0
    for k, d in enumerate(move):
        if travelled + d > resolution:
            keep.append(k)
            travelled = 0.0
        travelled += d
    last = move.size
    if keep[-1] != last:
        keep.append(last)
    return np.unique(np.array(keep, dtype=int))


@dataclass
class TrainCheckResult:
    """Outcome of :func:`check_train`.

    Attributes
    ----------
    ok : bool
        Every body inside the shrunk free space at every checked sample, every |phi_i| <=
        phi_max at every sample, and the goal reached within ``tracker.goal_tolerance``.
    t : (N,) array
        Times [s] of the checked samples (consecutive ones at most ``resolution`` of corner
        travel apart).
    s : (N,) array
        The reference's travelled distance [m] at ``t`` (flat during cusp dwells).
    poses : (N, 3) array
        The simulated last trailer's pose (x, y, theta) [m, m, rad].
    reference : (N, 3) array
        The reference pose of the last trailer at ``t``.
    headings : (N, n+1) array
        Simulated headings [rad]; ``x, y`` (N, n+1) the bodies' positions [m].
    max_abs_phi : (n,) array
        Largest |phi_i| over all simulated samples [rad].
    min_clearance : float
        Smallest distance [m] of any body to the walls beyond its margin at the checked samples
        (its distance to the walls minus its margin); negative if a body reaches into its
        margin, by how far.
    max_tracking_error : float
        Largest distance [m] of the last trailer from its reference sample at the same time.
    max_lateral_error, max_heading_error : float
        Largest |lateral error| [m] (in the reference's frame) and |heading error| [rad].
    goal_error : (float, float)
        Distance [m] and |heading error| [rad] of the last trailer to the goal at the first
        control instant at or after the reference's end within ``tracker.goal_tolerance``
        (where the co-simulation stops with ``goal_reached``), else at the end of the run.
    run : EngineRun
        The engine's closed-loop run checked (every control instant).
    simulated_t, simulated_headings : (M,) and (M, n+1) arrays
        Every simulated sample (control instants and the subdivisions of the check): times [s]
        and headings [rad].
    failure : dict or None
        First failure: ``kind`` ("collision", "joint_limit" or "goal_missed"), ``body``
        (0 robot .. n), ``t`` [s], ``s`` [m] (reference progress), ``direction`` (of the
        reference's last moving phase at ``t``: PUSH or PULL), ``x``, ``y`` [m] (the overlap
        point for collisions, else the body's position), ``phi`` [rad] for joint failures,
        ``distance`` [m] and ``heading_error`` [rad] for a missed goal.
    collisions : list of (int, int)
        (checked sample index, body) of every sample outside the free space.
    wall_clearance : float
        Smallest distance [m] of any body to the walls (the free space's boundary) at the
        checked samples, margins not counted.
    """

    ok: bool
    t: np.ndarray
    s: np.ndarray
    poses: np.ndarray
    reference: np.ndarray
    headings: np.ndarray
    x: np.ndarray
    y: np.ndarray
    max_abs_phi: np.ndarray
    min_clearance: float
    max_tracking_error: float
    max_lateral_error: float
    max_heading_error: float
    goal_error: tuple
    run: EngineRun
    simulated_t: np.ndarray
    simulated_headings: np.ndarray
    failure: dict | None = None
    collisions: list = field(default_factory=list)
    wall_clearance: float = math.nan

    def headings_at(self, t) -> np.ndarray:
        """Simulated headings [rad] at times ``t`` [s] (linear interpolation), (len(t), n+1)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return np.column_stack([np.interp(t, self.simulated_t, heading)
                                for heading in self.simulated_headings.T])


def check_train(
    world: World,
    train: Train,
    start: Sequence[float],
    segments: Sequence[Segment],
    start_headings: Sequence[float] | None = None,
    margin: float | Sequence[float] = 0.0,
    resolution: float = 0.01,
    tracker: TrackerConfig | None = None,
    run: EngineRun | None = None,
    self_collision: bool = False,
    measure: bool = True,
    field=None,
) -> TrainCheckResult:
    """Simulate the co-simulation's closed loop along the path and test footprints, joints, goal.

    Parameters
    ----------
    world, train : World, Train
    start : (x, y, theta)
        Last trailer's start pose [m, m, rad], chain convention.
    segments : sequence of Segment
    start_headings : (n+1,) or None
        Start headings [rad]; None is a straight chain (all equal to ``start[2]``).
    margin : float or (n+1,) sequence
        Clearance [m] every body (or each body, robot first) must keep from the blocked space.
    resolution : float
        Largest corner travel [m] of any body between checked samples.
    tracker : TrackerConfig or None
        Controller, reference speed, cusp dwell and simulation settings; None: the defaults.
    run : EngineRun or None
        The engine's closed loop along this reference from the start, already simulated (e.g.
        by the planner's :class:`~pushtrain.planner.propagate.Propagator`, which runs the same
        loop): checked instead of a new :func:`~pushtrain.core.engine.simulate` run.
    self_collision : bool
        Also test bodies that are not neighbours in the chain (i, j >= i + 2) against
        overlapping each other (failure kind ``"self_collision"``).
    measure : bool
        Measure the clearances (``min_clearance``, ``wall_clearance``; NaN without): the
        containment test alone is several times faster.
    field : DistanceField or None
        The map's distance field: a body whose axle midpoint is farther from the walls than its
        whole reach plus its margin (and 2 mm for the field's interpolation) is inside without
        a polygon test, and only bodies that can be the closest to a wall are measured (a body
        at distance d from its midpoint is between d - reach and d from the walls). Same
        results, much faster in wide spaces.
    """
    tracker = tracker or TrackerConfig()
    n = train.n
    theta0 = (
        np.full(n + 1, float(start[2]))
        if start_headings is None
        else np.asarray(start_headings, dtype=float).reshape(-1)
    )
    if theta0.size != n + 1:
        raise PlanningInputError(f"start_headings has {theta0.size} entries; need n + 1 = {n + 1}")
    if not (math.isfinite(resolution) and resolution > 0.0):
        raise PlanningInputError(f"resolution = {resolution!r} m: must be finite and > 0")
    controller = tracker.controller_for(train.geometry)
    margins = np.broadcast_to(np.asarray(margin, dtype=float), (n + 1,))
    regions = {m: world.eroded(m) for m in sorted(set(margins.tolist()))}
    reference = Reference.from_segments(start, segments, tracker.speed, tracker.cusp_dwell)
    if run is None:
        run = simulate(train.geometry, reference, theta0, controller, tracker.step,
                       tracker.settle_time)
        if run.violation is not None:
            raise ControllerError(f"the closed loop stopped at t = {run.violation.t:.6g} s: "
                                  f"{run.violation.reason} (value {run.violation.value:g})")
    traj = _Samples.of_run(run, reference)
    traj, x_all, y_all, corners = _refine(traj, train.geometry, train, resolution, controller)
    move = np.linalg.norm(np.diff(corners, axis=0), axis=-1).max(axis=(1, 2))
    keep = _thin(move, resolution)
    headings_all = traj.state[:, 2:]
    _, (t_knots, s_knots) = reference_times(segments, tracker.speed, tracker.cusp_dwell, [0.0])
    s_all = np.interp(traj.t, t_knots, s_knots)

    # tracking errors of the last trailer (at every sample, against the reference at that time)
    last = np.column_stack([x_all[:, -1], y_all[:, -1], headings_all[:, -1]])
    dx, dy = last[:, 0] - traj.reference[:, 0], last[:, 1] - traj.reference[:, 1]
    c, s_ = np.cos(traj.reference[:, 2]), np.sin(traj.reference[:, 2])
    lateral = -s_ * dx + c * dy
    heading_err = wrap_angle(last[:, 2] - traj.reference[:, 2])
    # goal test as the master's: the first control instant at or after t_end within tolerance
    # (the co-simulation stops there), else the end of the run
    goal = reference.goal
    after = np.flatnonzero(traj.control & (traj.t >= reference.t_end - 1e-12))
    dist = np.hypot(last[after, 0] - goal[0], last[after, 1] - goal[1])
    head = np.abs(wrap_angle(last[after, 2] - goal[2]))
    k_goal = after[-1] if after.size else traj.t.size - 1
    if tracker.goal_tolerance is not None and after.size:
        tol_pos, tol_head = tracker.goal_tolerance
        within = np.flatnonzero((dist <= tol_pos) & (head <= tol_head))
        if within.size:
            k_goal = after[within[0]]
    goal_dist = float(math.hypot(last[k_goal, 0] - goal[0], last[k_goal, 1] - goal[1]))
    goal_head = abs(wrap_scalar(last[k_goal, 2] - goal[2]))

    # footprints at the checked samples, joints at every sample
    travel = np.concatenate(([0.0], np.cumsum(move)))[keep]
    inside, clear, walls, polys = _footprints(world, train, corners[keep], x_all[keep],
                                              y_all[keep], margins, regions, measure, field,
                                              travel)
    phi = joint_angles(headings_all)
    abs_phi = np.abs(phi)
    moving_dir = _last_moving_direction(traj.direction, segments)

    failure = None
    collisions = [(int(k), int(i)) for k, i in zip(*np.nonzero(~inside), strict=True)]
    k_coll = np.flatnonzero(~inside.all(axis=1))
    k_joint = np.flatnonzero((abs_phi > train.phi_max).any(axis=1))
    t_coll = traj.t[keep[k_coll[0]]] if k_coll.size else math.inf
    t_joint = traj.t[k_joint[0]] if k_joint.size else math.inf
    folded = None
    if self_collision:

        folded = self_overlap(train, x_all[keep], y_all[keep], headings_all[keep])
    t_fold = traj.t[keep[folded[0]]] if folded is not None else math.inf

    def where(k):
        return {"t": float(traj.t[k]), "s": float(s_all[k]), "direction": int(moving_dir[k])}

    if folded is not None and t_fold < min(t_coll, t_joint):
        kf, i, j, px, py = folded
        k = int(keep[kf])
        failure = {"kind": "self_collision", "body": i, "other": j, **where(k), "x": px, "y": py}
    elif k_coll.size and t_coll <= t_joint:
        kc = int(k_coll[0])
        i = int(np.flatnonzero(~inside[kc])[0])
        k = int(keep[kc])
        body_poly = shapely.polygons(corners[keep[kc], i])
        outside = body_poly.difference(regions[float(margins[i])])
        point = outside.representative_point() if not outside.is_empty else body_poly.centroid
        failure = {"kind": "collision", "body": i, **where(k), "x": float(point.x),
                   "y": float(point.y), "body_x": float(x_all[k, i]), "body_y": float(y_all[k, i]),
                   "theta": float(headings_all[k, i])}
    elif k_joint.size:
        k = int(k_joint[0])
        j = int(np.argmax(abs_phi[k]))
        failure = {"kind": "joint_limit", "body": j + 1, **where(k), "x": float(x_all[k, j + 1]),
                   "y": float(y_all[k, j + 1]), "phi": float(phi[k, j])}
    elif tracker.goal_tolerance is not None and (
        goal_dist > tracker.goal_tolerance[0] or goal_head > tracker.goal_tolerance[1]
    ):
        k = traj.t.size - 1
        failure = {"kind": "goal_missed", "body": n, **where(k), "x": float(last[k, 0]),
                   "y": float(last[k, 1]), "distance": goal_dist, "heading_error": goal_head}
    log.debug("train check: %s; %d steps, %d checked samples, max tracking error %.3f m",
              "ok" if failure is None else failure["kind"], int(traj.control.sum()), keep.size,
              float(np.hypot(dx, dy).max()))
    return TrainCheckResult(
        ok=failure is None, t=traj.t[keep], s=s_all[keep], poses=last[keep],
        reference=traj.reference[keep], headings=headings_all[keep], x=x_all[keep],
        y=y_all[keep], max_abs_phi=abs_phi.max(axis=0),
        min_clearance=float(np.nanmin(clear)) if np.isfinite(clear).any() else math.nan,
        max_tracking_error=float(np.hypot(dx, dy).max()),
        max_lateral_error=float(np.abs(lateral).max()),
        max_heading_error=float(np.abs(heading_err).max()), goal_error=(goal_dist, goal_head),
        run=run, simulated_t=traj.t, simulated_headings=headings_all, failure=failure,
        collisions=collisions, wall_clearance=walls,
    )


def _footprints(world: World, train: Train, corners, x, y, margins, regions, measure: bool,
                field, travel=None):
    """Containment (N, n+1) of every body in its eroded region, its clearance beyond the margin
    (N, n+1; NaN where not measured), the smallest distance to the walls and the polygons
    made (an object array, None where skipped). See :func:`check_train`'s ``field``.
    ``travel`` (N,): the corner travel [m] from the first sample, which bounds how much any
    body's distance to the walls changes between two samples (see :func:`_nearest_gaps`)."""
    n1 = x.shape[1]
    if field is None:
        need = np.ones(x.shape, dtype=bool)
        lower = upper = None
    else:
        reach = np.array([math.hypot(abs(b.offset) + 0.5 * b.length, 0.5 * b.width)
                          for b in train.bodies])
        d = field.at(x, y)
        need = d < reach[None, :] + margins[None, :] + 0.002
        lower, upper = d - reach[None, :], d
    polys = np.full(x.shape, None, dtype=object)
    if need.any():
        polys[need] = shapely.polygons(corners[need])
    inside = np.ones(x.shape, dtype=bool)
    clear = np.full(x.shape, math.nan)
    measured = need.copy()
    if measure and lower is not None:
        # only bodies that can be the closest to a wall, or the closest beyond their margin,
        # are measured
        beyond_lo, beyond_up = lower - margins[None, :], upper - margins[None, :]
        measured |= (lower <= upper.min() + 1e-9) | (beyond_lo <= beyond_up.min() + 1e-9)
        todo = measured & ~need
        if todo.any():
            polys[todo] = shapely.polygons(corners[todo])
    for m, region in regions.items():
        cols = np.zeros(n1, dtype=bool)
        cols[np.flatnonzero(margins == m)] = True
        sel = need & cols[None, :]
        if sel.any():
            inside[sel] = shapely.contains(region, polys[sel])
    walls = math.nan
    if measure and measured.any():
        # a body's distance beyond its margin is its distance to the walls minus the margin
        # (the distance to the level set {d = m} of the distance to the walls is d - m)
        gap = np.full(x.shape, np.inf)
        far = measured & inside
        limit = None if upper is None else _measure_limit(field, upper, margins, far)
        if limit is not None:
            # only the smallest distances are reported: bodies that cannot come within the
            # limit (by the field, to within its slack) are not measured, the others' search
            # stops at it
            far &= lower - (1.5 * field.resolution + 0.002) <= limit
            if travel is None:
                gap[far] = world.wall_distance(polys[far], max_distance=limit)
            else:
                gap[far] = _nearest_gaps(world, polys, far, travel, margins, limit)[far]
            gap[measured & ~inside] = world.wall_distance(polys[measured & ~inside])
        else:
            gap[measured] = world.wall_distance(polys[measured])
        # a body inside its eroded region (within the free space) is covered by the free space
        covered = inside.copy()
        loose = measured & ~inside
        if loose.any():
            covered[loose] = shapely.covers(world.eroded(0.0), polys[loose])  # thread's copy
        gap = np.where(covered, gap, -gap)
        measured &= np.isfinite(gap)
        clear[measured] = (gap - np.broadcast_to(margins[None, :], x.shape))[measured]
        walls = float(np.min(gap[measured])) if measured.any() else math.nan
    clear = np.where(inside, np.abs(clear), -np.abs(clear))
    return inside, clear, walls, polys


def _nearest_gaps(world: World, polys, sel, travel, margins, limit: float,
                  spacing: float = 0.1) -> np.ndarray:
    """Distances [m] to the walls of the bodies ``sel`` (N, n+1) that can be the smallest, or
    the smallest beyond their margin (``inf`` for the others). A body moved rigidly so that no
    corner travels more than t is within t of where it was (a rigid motion moves no point
    farther than a corner), so its distance to the walls changed by at most t: the bodies at
    samples about ``spacing`` [m] of travel apart are measured first, and a body whose bound
    from its neighbouring measured samples (before and after) cannot reach the smallest found
    is not measured."""
    n_rows = sel.shape[0]
    gap = np.full(sel.shape, np.inf)
    bucket = np.floor(travel / spacing)
    anchor_rows = np.flatnonzero(np.r_[True, bucket[1:] != bucket[:-1]])
    anchors = np.zeros(sel.shape, dtype=bool)
    anchors[anchor_rows] = True
    anchors &= sel
    gap[anchors] = world.wall_distance(polys[anchors], max_distance=limit)
    # a body's distance is at least what was measured (at least the limit where nothing was
    # found within it); -inf where not measured: no bound from there
    known = np.where(anchors, np.minimum(gap, limit), -np.inf)
    # the measured sample before and after every row (anchor rows only), per body
    pos = np.searchsorted(anchor_rows, np.arange(n_rows), side="right") - 1
    before = anchor_rows[np.maximum(pos, 0)]
    after = anchor_rows[np.minimum(pos + 1, anchor_rows.size - 1)]
    lower = np.maximum(known[before] - np.abs(travel - travel[before])[:, None],
                       known[after] - np.abs(travel[after] - travel)[:, None])
    found = gap[anchors]
    best = float(found.min()) if found.size else math.inf
    best_beyond = (float((gap - margins[None, :])[anchors].min()) if found.size else math.inf)
    todo = sel & ~anchors & ((lower <= best + 1e-9)
                             | (lower - margins[None, :] <= best_beyond + 1e-9))
    if todo.any():
        gap[todo] = world.wall_distance(polys[todo], max_distance=limit)
    return gap


def _measure_limit(field, upper, margins, sel) -> float | None:
    """A distance [m] beyond which no body of ``sel`` can be the closest to the walls nor the
    closest beyond its margin (None: nothing to limit). A body is at most as far from the walls
    as its axle midpoint (inside its rectangle), whose distance is the field's value there
    (``upper``) to within 1.5 cells and 2 mm."""
    if not sel.any():
        return None
    slack = 1.5 * field.resolution + 0.002
    bound = (upper + slack)[sel]
    beyond = (upper + slack - margins[None, :])[sel]
    limit = max(float(bound.min()), float(beyond.min()) + float(margins.max()))
    return limit if math.isfinite(limit) else None


def _last_moving_direction(direction: np.ndarray, segments: Sequence[Segment]) -> np.ndarray:
    """Direction of the reference's current or last moving phase at every sample (PUSH/PULL)."""
    out = direction.copy()
    previous = segments[0].direction
    for k, d in enumerate(out):
        if d == 0:
            out[k] = previous
        else:
            previous = d
    return out

