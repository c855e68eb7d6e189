"""Whole-train check: predict the closed loop the co-simulation will run and test every body.

The planner plans the last trailer only. Here the whole train's motion along the plan is
predicted by running the co-simulation's own controller,
:class:`~pushtrain.core.controller.BackwardController`, in closed loop with the kinematic chain:

Reference
    ``Reference.from_segments(start, segments, tracker.speed, tracker.cusp_dwell)``, the same
    time-parameterized reference :meth:`~pushtrain.planner.path.PlannedPath.to_reference`
    hands to the co-simulation master.
Controller
    ``BackwardController(tracker.controller)`` (gains, robot limits, rate limits and its own
    chain model, from which the robot's pulling reference, a
    :class:`~pushtrain.core.pulling.PullGuide`, is built), called every ``tracker.step``
    seconds at ``t_k = k * step`` through the master's own per-step logic,
    :class:`~pushtrain.core.tracking.TrackingLoop`, with a perfect measurement (robot pose and
    joint angles ``phi_i = theta_{i-1} - theta_i``); the command is held over the step
    (zero-order hold) and the rate limits start from rest one step before t = 0, as in the
    master.
Plant
    The robot moves along its heading with the commanded ``(v0, w0)`` (no first-order velocity
    lag: the FMU's ``tau`` = 0.05 s is ignored, no slip), the trailers are towed:
    ``d(theta)/dt`` from the forward velocity map of :mod:`pushtrain.core.kinematics`
    (:func:`~pushtrain.core.kinematics.forward_velocities`, here as the fast scalar
    :func:`towed_rates`), with the train's own geometry (the controller's model may differ).
    The state ``(x0, y0, theta_0..theta_n)`` is integrated with RK4 over each step (the
    command is constant within a step). The error is that of the zero-order hold, first
    order in the step: on a bay plan with a cusp and 0.24 m transients (3 trailers) the last
    trailer's trajectory differs from a 0.002 s run by 2.4 cm with a 0.1 s step, 1.0 cm with
    0.05 s and 0.36 cm with the default 0.025 s (a test keeps it below 1 cm).
Start and end
    The last trailer starts at ``start`` with the given headings (the co-simulation's
    ``InitialState.behind_reference``), at rest. The run continues ``tracker.settle_time``
    seconds past the reference's end (the reference then rests and the robot brakes to a
    stop within its acceleration limit).

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

from pushtrain.core.controller import BackwardController, ControllerConfig
from pushtrain.core.kinematics import (
    ChainGeometry,
    body_positions_along,
    joint_angles,
    wrap_angle,
    wrap_scalar,
)
from pushtrain.core.ode import rk4_step
from pushtrain.core.reference import Reference, Segment
from pushtrain.core.tracking import TrackingLoop
from pushtrain.errors import PlanningInputError

from .world import Train, World

__all__ = [
    "TrackerConfig",
    "TrainCheckResult",
    "Trajectory",
    "body_positions_along",
    "check_train",
    "default_controller",
    "reference_times",
    "simulate_tracking",
    "towed_rates",
]

log = logging.getLogger(__name__)


def default_controller(geometry: ChainGeometry) -> ControllerConfig:
    """The scenario defaults of :class:`~pushtrain.core.controller.ControllerConfig` for a chain.

    Default gains (K_x = 1 1/s, K_y = 4 1/m², K_theta = 4 1/m), v_max = 0.1 m/s,
    w_max = 0.1 rad/s, acc_max = 0.2 m/s², alpha_max = 10 deg/s² (``mission/scenario.py``'s
    robot and controller sections) and ``geometry`` as the controller's chain model.
    """
    return ControllerConfig(geometry=geometry, v_max=0.1, w_max=0.1, acc_max=0.2,
                            alpha_max=math.radians(10.0))


@dataclass(frozen=True)
class TrackerConfig:
    """How the co-simulation will track the plan (what :func:`check_train` simulates).

    Parameters
    ----------
    controller : ControllerConfig or None
        The co-simulation's controller; None: :func:`default_controller` of the train's
        geometry.
    speed : float
        Reference speed |v_d| [m/s] on every segment without its own speed, > 0.
    cusp_dwell : float
        Rest [s] of the reference at every direction change, >= 0.
    step : float
        Control and integration step [s], > 0 (the controller is called every ``step``).
    settle_time : float
        Simulated time [s] past the reference's end, >= 0.
    goal_tolerance : (float, float) or None
        Position [m] and heading [rad] tolerance of the last trailer at the end of the run
        (the co-simulation's goal test); None: report the goal error only.
    """

    controller: ControllerConfig | None = None
    speed: float = 0.08
    cusp_dwell: float = 1.0
    step: float = 0.025
    settle_time: float = 2.0
    goal_tolerance: tuple[float, float] | None = (0.05, math.radians(5.0))

    def __post_init__(self):
        if self.controller is not None and not isinstance(self.controller, ControllerConfig):
            raise PlanningInputError(
                f"tracker.controller = {self.controller!r}: must be a ControllerConfig or None")
        checks = (("speed", None), ("step", None), ("cusp_dwell", 0.0), ("settle_time", 0.0))
        for key, low in checks:
            value = getattr(self, key)
            ok = isinstance(value, (int, float)) and math.isfinite(value)
            ok = ok and (value > 0.0 if low is None else value >= low)
            if not ok:
                allowed = "finite and > 0" if low is None else "finite and >= 0"
                raise PlanningInputError(f"tracker.{key} = {value!r}: must be {allowed}")
        if self.goal_tolerance is not None:
            tol = tuple(self.goal_tolerance)
            if len(tol) != 2 or not all(math.isfinite(a) and a > 0.0 for a in tol):
                raise PlanningInputError(
                    f"tracker.goal_tolerance = {self.goal_tolerance!r}: need None or two finite "
                    "numbers > 0 (position [m], heading [rad])")
            object.__setattr__(self, "goal_tolerance", (float(tol[0]), float(tol[1])))

    def controller_for(self, geometry: ChainGeometry) -> ControllerConfig:
        """The controller configuration used for a chain of ``geometry`` (checks its n)."""
        config = self.controller if self.controller is not None else default_controller(geometry)
        if config.geometry.n != geometry.n:
            raise PlanningInputError(
                f"tracker.controller has a chain model of n = {config.geometry.n} trailers; the "
                f"train has n = {geometry.n}")
        return config


def towed_rates(geometry: ChainGeometry):
    """A fast scalar form of :func:`pushtrain.core.kinematics.forward_velocities` (yaw rates).

    Returns ``f(theta, v0, w0) -> list`` of d(theta_i)/dt [rad/s], i = 0..n, for headings
    ``theta`` (n+1,) [rad] and the robot's (v0 [m/s], w0 [rad/s]): the same recursion
    v_i = c v_{i-1} + R_{i-1} s w_{i-1}, w_i = (s v_{i-1} - R_{i-1} c w_{i-1}) / F_i with
    c, s of phi_i = theta_{i-1} - theta_i.
    """
    front = [float(a) for a in geometry.front]
    rear = [float(a) for a in geometry.rear]
    n = geometry.n

    def rates(theta, v0: float, w0: float, cos=math.cos, sin=math.sin):
        w = [0.0] * (n + 1)
        v, w[0] = v0, w0
        for i in range(1, n + 1):
            phi = theta[i - 1] - theta[i]
            c, s = cos(phi), sin(phi)
            r = rear[i - 1]
            v, w[i] = c * v + r * s * w[i - 1], (s * v - r * c * w[i - 1]) / front[i - 1]
        return w

    return rates


def _robot_positions(state: np.ndarray, geometry: ChainGeometry):
    """Positions (x, y), each (N, n+1), of all bodies from states (N, 3 + n) = (x0, y0, theta)."""
    th = state[:, 2:]
    c, s = np.cos(th), np.sin(th)
    step_x = -geometry.rear * c[:, :-1] - geometry.front * c[:, 1:]
    step_y = -geometry.rear * s[:, :-1] - geometry.front * s[:, 1:]
    zero = np.zeros((state.shape[0], 1))
    x = state[:, :1] + np.concatenate((zero, np.cumsum(step_x, axis=1)), axis=1)
    y = state[:, 1:2] + np.concatenate((zero, np.cumsum(step_y, axis=1)), axis=1)
    return x, y


def reference_times(segments: Sequence[Segment], speed: float, cusp_dwell: float, s):
    """Time [s] at which the reference of :class:`~pushtrain.core.reference.Reference` (t0 = 0)
    reaches the travelled distance ``s`` [m] (array); at a cusp the arrival (start of the dwell).

    Returns ``(t, knots)`` where ``knots = (t_knots, s_knots)`` is the piecewise-linear map
    t -> s (flat during dwells) for :func:`numpy.interp`.
    """
    t_k, s_k = [0.0], [0.0]
    t, pos, previous = 0.0, 0.0, None
    starts, ends, seg_t0, seg_speed = [], [], [], []
    for seg in segments:
        if previous is not None and seg.direction != previous:
            t += cusp_dwell
            t_k.append(t), s_k.append(pos)
        v = speed if seg.speed is None else seg.speed
        starts.append(pos), seg_t0.append(t), seg_speed.append(v)
        t += seg.length / v
        pos += seg.length
        ends.append(pos)
        t_k.append(t), s_k.append(pos)
        previous = seg.direction
    s = np.asarray(s, dtype=float)
    j = np.clip(np.searchsorted(np.array(ends), s, side="left"), 0, len(ends) - 1)
    times = np.array(seg_t0)[j] + (s - np.array(starts)[j]) / np.array(seg_speed)[j]
    return times, (np.array(t_k), np.array(s_k))


@dataclass
class Trajectory:
    """A closed-loop run of :func:`simulate_tracking` (every row one sample).

    Attributes
    ----------
    t : (K,) array
        Times [s]: the control instants ``k * step`` and, where a step was subdivided for the
        footprint test, intermediate times.
    state : (K, 3 + n) array
        Robot position and all headings ``(x0, y0, theta_0..theta_n)`` [m, m, rad].
    command : (K, 2) array
        Robot command (v0 [m/s], w0 [rad/s]) held from this sample on.
    reference : (K, 3) array
        The last trailer's reference pose (x, y, theta) at ``t``.
    direction : (K,) int array
        Reference direction at ``t`` (PUSH +1, PULL -1, REST 0).
    control : (K,) bool array
        True at the control instants (False at subdivision samples).
    """

    t: np.ndarray
    state: np.ndarray
    command: np.ndarray
    reference: np.ndarray
    direction: np.ndarray
    control: np.ndarray


def _rk4_step(rates, state, v0: float, w0: float, h: float):
    """One RK4 step of (x0, y0, theta...) under the constant robot command (v0, w0)."""
    def f(_t, z):
        th = z[2:]
        return [v0 * math.cos(th[0]), v0 * math.sin(th[0])] + rates(th, v0, w0)

    return rk4_step(f, 0.0, state, h)


class _Measurement:
    """Perfect measurement handed to the controller (robot pose and joint angles)."""

    __slots__ = ("x0", "y0", "theta0", "phi")
    last_pose = None  # the last trailer's pose is estimated from the joints, as in the master

    def __init__(self, state):
        self.x0, self.y0, self.theta0 = state[0], state[1], state[2]
        th = state[2:]
        self.phi = [th[i - 1] - th[i] for i in range(1, len(th))]


def simulate_tracking(
    geometry: ChainGeometry,
    reference: Reference,
    start_headings: Sequence[float],
    controller: ControllerConfig,
    step: float = 0.025,
    settle_time: float = 2.0,
) -> Trajectory:
    """Run ``controller`` in closed loop with the kinematic chain along ``reference``.

    Parameters
    ----------
    geometry : ChainGeometry
        The plant's chain (the controller uses its own model ``controller.geometry``).
    reference : Reference
        The last trailer's reference (t0 = 0); the last trailer starts at ``reference.start``.
    start_headings : (n+1,)
        Start headings [rad] of robot and trailers (the last equals the start theta).
    controller : ControllerConfig
    step : float
        Control and RK4 step [s].
    settle_time : float
        Time [s] simulated past ``reference.t_end``.

    Returns
    -------
    Trajectory
        Samples at the control instants ``k * step`` (k = 0..K-1, the last one at or after
        ``t_end + settle_time``).
    """
    ctrl = BackwardController(controller)
    ctrl.reset(0.0, 0.0, -step)
    loop = TrackingLoop(ctrl, reference)
    rates = towed_rates(geometry)
    th0 = np.asarray(start_headings, dtype=float)
    x, y = body_positions_along(np.asarray(reference.start, dtype=float)[None, :], th0[None, :],
                                geometry)
    state = [float(x[0, 0]), float(y[0, 0])] + [float(a) for a in th0]
    n_steps = int(math.ceil((reference.t_end + settle_time) / step - 1e-9))
    states, commands, refs, dirs = [], [], [], []
    for k in range(n_steps + 1):
        t = k * step
        v0, w0, _, ref = loop.command(t, _Measurement(state))
        states.append(state), commands.append((v0, w0))
        refs.append((ref.x, ref.y, ref.theta)), dirs.append(ref.direction)
        if k < n_steps:
            state = _rk4_step(rates, state, v0, w0, step)
    return Trajectory(step * np.arange(n_steps + 1), np.array(states), np.array(commands),
                      np.array(refs), np.array(dirs, dtype=int), np.ones(n_steps + 1, dtype=bool))


def _refine(traj: Trajectory, geometry: ChainGeometry, train: Train, resolution: float):
    """Subdivide the steps in which some corner moves more than ``resolution`` (RK4 substeps
    under the held command). Returns (trajectory, x, y, corners)."""
    rates = towed_rates(geometry)
    x, y = _robot_positions(traj.state, geometry)
    corners = _corners(train, x, y, traj.state[:, 2:])
    move = np.linalg.norm(np.diff(corners, axis=0), axis=-1).max(axis=(1, 2))
    bad = np.flatnonzero(move > resolution)
    if not bad.size:
        return traj, x, y, corners
    rows = {name: [getattr(traj, name)] for name in ("t", "state", "command", "reference",
                                                     "direction", "control")}
    for k in bad:
        m = int(math.ceil(move[k] / resolution * 1.05))
        h = (traj.t[k + 1] - traj.t[k]) / m
        v0, w0 = traj.command[k]
        z = [float(a) for a in traj.state[k]]
        for j in range(1, m):
            z = _rk4_step(rates, z, v0, w0, h)
            rows["t"].append([traj.t[k] + j * h]), rows["state"].append([z])
            rows["command"].append([traj.command[k]]), rows["reference"].append([traj.reference[k]])
            rows["direction"].append([traj.direction[k]]), rows["control"].append([False])
    merged = {name: np.concatenate([np.asarray(r) for r in parts]) for name, parts in rows.items()}
    order = np.argsort(merged["t"], kind="stable")
    traj = Trajectory(**{name: value[order] for name, value in merged.items()})
    x, y = _robot_positions(traj.state, geometry)
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
    trajectory : Trajectory
        Every simulated sample (control instants and subdivisions).
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
    trajectory: Trajectory
    failure: dict | None = None
    collisions: list = field(default_factory=list)
    wall_clearance: float = math.nan

    def headings_at(self, t) -> np.ndarray:
        """Simulated headings [rad] at times ``t`` [s] (linear interpolation), (len(t), n+1)."""
        tr = self.trajectory
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return np.column_stack([np.interp(t, tr.t, tr.state[:, 2 + i])
                                for i in range(tr.state.shape[1] - 2)])


def check_train(
    world: World,
    train: Train,
    start: Sequence[float],
    segments: Sequence[Segment],
    start_headings: Sequence[float] | None = None,
    margin: float | Sequence[float] = 0.0,
    resolution: float = 0.01,
    tracker: TrackerConfig | None = None,
    trajectory: Trajectory | None = None,
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
    trajectory : Trajectory or None
        The closed loop along this reference already simulated (e.g. by the planner's
        :class:`~pushtrain.planner.propagate.Propagator`, which runs the same loop): checked
        instead of a new :func:`simulate_tracking` run.
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
    traj = trajectory
    if traj is None:
        traj = simulate_tracking(train.geometry, reference, theta0, controller, tracker.step,
                                 tracker.settle_time)
    traj, x_all, y_all, corners = _refine(traj, train.geometry, train, resolution)
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
    inside, clear, walls, polys = _footprints(world, train, corners[keep], x_all[keep],
                                              y_all[keep], margins, regions, measure, field)
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
        from .footprint import _self_overlap

        folded = _self_overlap(train, x_all[keep], y_all[keep], headings_all[keep])
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
        trajectory=traj, failure=failure, collisions=collisions, wall_clearance=walls,
    )


def _footprints(world: World, train: Train, corners, x, y, margins, regions, measure: bool,
                field):
    """Containment (N, n+1) of every body in its eroded region, its clearance beyond the margin
    (N, n+1; NaN where not measured), the smallest distance to the walls and the polygons
    made (an object array, None where skipped). See :func:`check_train`'s ``field``."""
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
        gap = shapely.distance(world.free.boundary, polys[measured])
        covered = shapely.covers(world.free, polys[measured])
        gap = np.where(covered, gap, -gap)
        clear[measured] = gap - np.broadcast_to(margins[None, :], x.shape)[measured]
        walls = float(np.min(gap))
    clear = np.where(inside, np.abs(clear), -np.abs(clear))
    return inside, clear, walls, polys


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

