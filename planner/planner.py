"""Reeds-Shepp planning of the last trailer with OMPL, and the whole-train replanning loop.

This is the only module of pushtrain that imports ompl; OMPL's camelCase stays here and results
are converted to numpy at once.

Planner state: the last trailer's axle midpoint (x, y) and ``yaw`` = its direction of travel
when pushing, yaw = theta + pi (theta: chain heading, toward the robot). Reeds-Shepp "forward"
is therefore pushing (:data:`~pushtrain.core.reference.PUSH`, trailer leads) and "backward"
pulling (:data:`~pushtrain.core.reference.PULL`, robot leads).

Turning-radius rule (when :attr:`PlannerConfig.turning_radius` is None)::

    r = D / tan(phi_max / (2 (1 + transient_margin)))      D = max_i max(F_i, R_i)

i.e. the steady joint angle on the arc, 2 atan(D / r), is phi_max / (1 + transient_margin).
Entering an arc from a line does not overshoot the steady angle in the chain kinematics, but
switching between opposite arcs does: up to 1.46x the steady angle for 3 trailers and 1.56x for
10 (r = 0.9 .. 1.5 m, D = 0.52 m), so the default margin 0.6 covers both; tracking transients
of the closed loop need the rest. With phi_max = 90 deg and D = 0.52 m this gives r = 0.975 m.

Pulls: while pulling the robot leads on a reference of its own, computed backward in time from
a straight chain at the pull's end (:class:`~pushtrain.core.pulling.PullGuide`). Two rules keep
planned pulls within what that can do: the straight train at every pull's end must be free
(``straight_pull_ends``), and a pull must start near the chain it needs
(``pull_start_tolerance``).

Whole-train check and replanning: every plan is checked by simulating the co-simulation's
controller in closed loop with the chain (:mod:`pushtrain.planner.train_check`); a failure
changes the next attempt (larger radius, or a blocked region and more inflation, see
:func:`_next_attempt`) until a plan passes, ``max_attempts`` or ``time_budget`` run out.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np
import shapely
from shapely.geometry import Point, Polygon

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.kinematics import body_positions_along
from pushtrain.core.pulling import straight_chain_mismatch
from pushtrain.core.reference import PULL, PUSH, Segment

from pushtrain.errors import PlanningError, PlanningInputError
from .path import PlannedPath
from .reeds_shepp import Primitive, recover_primitives
from .train_check import TrackerConfig, check_train, reference_times
from .world import Train, World

from ompl import base as ob  # noqa: E402  (the one module that imports ompl)
from ompl import geometric as og  # noqa: E402
from ompl import util as ou  # noqa: E402

__all__ = [
    "PlannerConfig",
    "plan",
    "turning_radius_from_joint_limit",
    "PLANNERS",
    "ReedsSheppCurve",
    "rs_distance",
]

log = logging.getLogger(__name__)

# OMPL prints to stdout/stderr; library code must not. Every OMPL failure the planner can meet
# (invalid start/goal, no or approximate solution) becomes a PlanningError instead.
ou.setLogLevel(ou.LOG_NONE)

PLANNERS = ("rrtconnect", "restarts", "rrtstar", "bitstar", "prmstar")
"""Planner names: ``rrtconnect`` stops at its first solution; the others are anytime optimal."""

_ANYTIME = {"restarts", "rrtstar", "bitstar", "prmstar"}
_REFINE_RATIO = 1.2
_OPTIMIZING = {"rrtstar", "bitstar", "prmstar"}  # OMPL planners given a length objective


def _allocate_planner(name: str, si):
    """OMPL planner object for ``name``."""
    factory = {
        "rrtconnect": og.RRTConnect,
        "rrtstar": og.RRTstar,
        "bitstar": og.BITstar,
        "prmstar": og.PRMstar,
    }[name]
    return factory(si)


def turning_radius_from_joint_limit(phi_max: float, link: float, transient_margin: float = 0.6) -> float:
    """Turning radius [m] whose steady joint angle is ``phi_max / (1 + transient_margin)``.

    ``r = link / tan(phi_max / (2 (1 + transient_margin)))`` with ``phi_max`` [rad] in (0, pi)
    and ``link`` the largest hitch link [m].
    """
    if not (0.0 < phi_max < math.pi):
        raise PlanningInputError(f"phi_max = {phi_max!r} rad: allowed is (0, pi)")
    if not (transient_margin >= 0.0 and math.isfinite(transient_margin)):
        raise PlanningInputError(f"transient_margin = {transient_margin!r}: must be finite and >= 0")
    return float(link / math.tan(phi_max / (2.0 * (1.0 + transient_margin))))


@dataclass(frozen=True)
class PlannerConfig:
    """Planner settings (SI units).

    Parameters
    ----------
    turning_radius : float or None
        Reeds-Shepp radius [m]; None derives it from the train's ``phi_max`` with
        :func:`turning_radius_from_joint_limit` and ``transient_margin``.
    transient_margin : float
        Margin of the radius rule (0.6: steady joint angle = phi_max / 1.6).
    planner : str
        One of :data:`PLANNERS`; ``rrtconnect`` (default) returns its first solution fast,
        the others improve the path for ``anytime_time`` seconds: ``restarts`` repeats
        RRTConnect, simplification and a local search on the path's states with new seeds and
        keeps the shortest; ``rrtstar``,
        ``bitstar`` and ``prmstar`` are OMPL's asymptotically optimal planners.
    time_budget : float
        Wall-clock budget [s] for planning and all replanning together.
    anytime_time : float
        Solve time [s] of one anytime-planner run (capped by what is left of the budget).
    seed : int or None
        OMPL random seed (>= 1). Same seed, same plan for ``rrtconnect``; anytime planners stop
        on time and are reproducible only if the machine is equally fast. None: OMPL's own seed.
    simplify : bool
        Shorten the solution: OMPL's ``reduceVertices``, then a greedy shortcut (each kept
        state jumps to the farthest later state one free curve reaches).
    inflation : float
        Clearance [m] every body keeps from obstacles (planning and train check).
    offtrack_allowance : float
        Extra clearance [m] for the last trailer while planning only, to leave room for the
        followers that cut inside corners in transients.
    planning_resolution : float
        Motion-validation step [m] of OMPL along a local path (coarse; re-checked densely).
    check_resolution : float
        Dense re-check step [m], <= 0.01: largest corner displacement between checked samples.
    max_attempts : int
        Plans tried in total (the first plus replans after failed train checks).
    radius_growth, inflation_growth, block_radius : float
        Replanning after a failed train check: radius factor per joint-limit failure, missed
        goal or collision of a leading body while pulling; added inflation [m] per further
        collision, and half-size [m] of the region blocked around a collision (see
        :func:`_next_attempt`).
    check_train : bool
        Run the whole-train check (disable only to study the last trailer alone): a
        closed-loop simulation of the co-simulation's controller along the plan
        (:func:`~pushtrain.planner.train_check.check_train`).
    allow_pull_arcs : bool
        Let local Reeds-Shepp curves turn while pulling (default). False restricts pulling to
        straight lines (much harder for the sampling planners; for studies only).
    controller : ControllerConfig or None
        The co-simulation's controller, simulated by the whole-train check
        (:class:`~pushtrain.planner.train_check.TrackerConfig`); None: the scenario defaults of
        :func:`~pushtrain.planner.train_check.default_controller` for the train.
    speed : float
        Reference speed [m/s] the co-simulation will use (``PlannedPath.to_reference``).
    cusp_dwell : float
        Rest [s] of the reference at each direction change in the co-simulation.
    straight_pull_ends : bool
        Require, at the end of every pulling run (a cusp, or the goal), the train drawn out
        straight ahead of the last trailer to be free (with ``inflation``): the robot's pulling
        reference ends with the chain straight there
        (:class:`~pushtrain.core.pulling.PullGuide`). Checked inside a local curve, at the
        goal, and at the junctions of the finished path; a junction that breaks it is repaired
        (its state dropped or moved nearby), else the path is re-solved with the next seed
        (``PlanningError`` reason ``pull_end_blocked`` if none is left). Without it the sampling planner ends pulls on
        arcs whose tangent points into a wall (bay, seeds 1-20: 0 first plans passed the
        closed-loop check).
    rrt_range : float or None
        Longest tree extension [m] of RRTConnect (OMPL's ``range``); None: 1.3 turning radii.
        OMPL's default (a fifth of the map's extent, about 2.5 m here) makes most extensions
        in a narrow corridor fail late: on the 1.5 m L-corridor 1.3 radii found a plan within
        0.1 s for 40 of 40 seeds against 35 of 40 (``benchmarks/bench_planner.py``).
    pull_start_tolerance : float or None
        Largest distance [m] between a body of the chain a pull needs at its start (drawn back
        from a straight chain at the pull's end, see
        :func:`~pushtrain.core.pulling.straight_chain_mismatch`) and the same body of the
        chain it starts from: the start
        headings at the start state, a straight chain elsewhere. Checked for pulls that start a
        local curve. The robot cannot make up this difference while pulling (the chain behind
        it only follows), so the last trailer would leave its path by about as much. 0.4 m
        passed the most first plans on the bay when it was chosen (seeds 1-20: 0.15 m 70 %,
        0.4 m 90 %, 0.7 m 70 %, rule off 65 %).
        None switches the rule off.
    """

    turning_radius: float | None = None
    transient_margin: float = 0.6
    planner: str = "rrtconnect"
    time_budget: float = 2.0
    anytime_time: float = 0.5
    seed: int | None = 1
    simplify: bool = True
    inflation: float = 0.05
    offtrack_allowance: float = 0.1
    planning_resolution: float = 0.1
    check_resolution: float = 0.01
    max_attempts: int = 6
    radius_growth: float = 1.2
    inflation_growth: float = 0.05
    block_radius: float = 0.25
    check_train: bool = True
    allow_pull_arcs: bool = True
    controller: ControllerConfig | None = None
    speed: float = 0.08
    cusp_dwell: float = 1.0
    straight_pull_ends: bool = True
    pull_start_tolerance: float | None = 0.4
    rrt_range: float | None = None

    def __post_init__(self):
        name = str(self.planner).lower()
        if name not in PLANNERS:
            raise PlanningInputError(f"planner = {self.planner!r}: allowed are {PLANNERS}")
        object.__setattr__(self, "planner", name)
        positive = ("time_budget", "anytime_time", "planning_resolution", "check_resolution",
                    "radius_growth", "block_radius")
        for key in positive:
            value = getattr(self, key)
            if not (math.isfinite(value) and value > 0.0):
                raise PlanningInputError(f"{key} = {value!r}: must be finite and > 0")
        for key in ("inflation", "offtrack_allowance", "inflation_growth", "transient_margin"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value >= 0.0):
                raise PlanningInputError(f"{key} = {value!r}: must be finite and >= 0")
        if self.rrt_range is not None and not (
            isinstance(self.rrt_range, (int, float)) and math.isfinite(self.rrt_range)
            and self.rrt_range > 0.0
        ):
            raise PlanningInputError(f"rrt_range = {self.rrt_range!r} m: must be None or > 0")
        if self.pull_start_tolerance is not None and not (
            isinstance(self.pull_start_tolerance, (int, float))
            and math.isfinite(self.pull_start_tolerance) and self.pull_start_tolerance >= 0.0
        ):
            raise PlanningInputError(
                f"pull_start_tolerance = {self.pull_start_tolerance!r} m: must be None or finite "
                "and >= 0")
        if self.turning_radius is not None and not (
            math.isfinite(self.turning_radius) and self.turning_radius > 0.0
        ):
            raise PlanningInputError(f"turning_radius = {self.turning_radius!r} m: must be > 0")
        if self.check_resolution > 0.01:
            raise PlanningInputError(
                f"check_resolution = {self.check_resolution!r} m: must be <= 0.01"
            )
        if self.seed is not None and int(self.seed) < 1:
            raise PlanningInputError(f"seed = {self.seed!r}: must be an integer >= 1 or None")
        if int(self.max_attempts) < 1:
            raise PlanningInputError(f"max_attempts = {self.max_attempts!r}: must be >= 1")
        self.tracker()  # validates controller, speed and cusp_dwell

    def tracker(self) -> TrackerConfig:
        """What the whole-train check simulates: controller, reference speed and cusp dwell."""
        return TrackerConfig(controller=self.controller, speed=self.speed,
                             cusp_dwell=self.cusp_dwell)

    def extension_for(self, radius: float) -> float:
        """RRTConnect's longest tree extension [m] for turning ``radius`` [m]."""
        if self.rrt_range is not None:
            return float(self.rrt_range)
        return 1.3 * float(radius)

    def radius_for(self, train: Train) -> float:
        """The turning radius [m] used for ``train``."""
        if self.turning_radius is not None:
            return float(self.turning_radius)
        return turning_radius_from_joint_limit(train.phi_max, train.max_link(), self.transient_margin)


# ---------------------------------------------------------------------- OMPL helpers
def _set_seed(seed: int) -> None:
    """Seed OMPL's generator. OMPL logs an error when re-seeding after the first draw but does
    re-seed (checked by the tests); that message is silenced here."""
    level = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)
    try:
        ou.RNG.setSeed(int(seed))
    finally:
        ou.setLogLevel(level)


def _space(rho: float, bounds) -> "ob.ReedsSheppStateSpace":
    space = ob.ReedsSheppStateSpace(float(rho))
    b = ob.RealVectorBounds(2)
    b.setLow(0, bounds[0])
    b.setLow(1, bounds[1])
    b.setHigh(0, bounds[2])
    b.setHigh(1, bounds[3])
    space.setBounds(b)
    return space


def _yaw_wrap(yaw: float) -> float:
    """Yaw in [-pi, pi) as OMPL's SO2 bounds require."""
    return (float(yaw) + math.pi) % (2.0 * math.pi) - math.pi


class ReedsSheppCurve:
    """OMPL's Reeds-Shepp curve between two planner states (x, y, yaw) for radius ``rho``.

    ``length`` is OMPL's ``distance`` [m]; :meth:`interpolate` is OMPL's ``interpolate`` at
    the fraction t in [0, 1]; :meth:`primitives` recovers the line/arc pieces.
    """

    def __init__(self, rho: float, a: Sequence[float], b: Sequence[float]):
        pad = 2.0 * rho + 1.0
        lo = min(a[0], b[0]) - pad, min(a[1], b[1]) - pad
        hi = max(a[0], b[0]) + pad, max(a[1], b[1]) + pad
        self.rho = float(rho)
        self._space = _space(rho, (lo[0], lo[1], hi[0], hi[1]))
        self._a, self._b, self._out = (self._space.allocState() for _ in range(3))
        for state, pose in ((self._a, a), (self._b, b)):
            state.setX(float(pose[0]))
            state.setY(float(pose[1]))
            state.setYaw(_yaw_wrap(pose[2]))
        self.length = float(self._space.distance(self._a, self._b))

    def interpolate(self, t: float) -> tuple[float, float, float]:
        """Pose (x, y, yaw) at the fraction ``t`` of the curve."""
        self._space.interpolate(self._a, self._b, float(t), self._out)
        return self._out.getX(), self._out.getY(), self._out.getYaw()

    def primitives(self, tol: float = 1e-9) -> list[Primitive]:
        """Recovered line/arc pieces (see :mod:`pushtrain.planner.reeds_shepp`)."""
        return recover_primitives(self.interpolate, self.length, self.rho, tol)


def rs_distance(rho: float, a: Sequence[float], b: Sequence[float]) -> float:
    """Length [m] of the shortest Reeds-Shepp curve from pose ``a`` to ``b`` (x, y, yaw)."""
    return ReedsSheppCurve(rho, a, b).length


def primitives_to_segments(primitives: Sequence[Primitive], rho: float) -> list[Segment]:
    """Planner-frame primitives -> reference segments (forward = PUSH, backward = PULL).

    The chain heading theta = yaw + pi changes like yaw, so d(theta)/ds per metre travelled is
    +1/rho for a left arc driven forward, -1/rho backward, and the opposite for right arcs.
    """
    out = []
    for p in primitives:
        direction = PUSH if p.gear > 0 else PULL
        if p.turn == "S":
            out.append(Segment("line", p.length, 0.0, direction))
        else:
            k = (1.0 if p.turn == "L" else -1.0) * p.gear / rho
            out.append(Segment("arc", p.length, k, direction))
    return out


def _merge(segments: Sequence[Segment]) -> list[Segment]:
    out: list[Segment] = []
    for g in segments:
        if out and (out[-1].kind, out[-1].curvature, out[-1].direction) == (
            g.kind, g.curvature, g.direction
        ):
            out[-1] = Segment(g.kind, out[-1].length + g.length, g.curvature, g.direction)
        else:
            out.append(g)
    return out


def _sample_into(rows: list, space, a, b, m: int, tmp) -> None:
    """Append to ``rows`` the states (x, y, yaw) of OMPL's curve ``a -> b`` at the fractions
    k/m, k = 1..m (``tmp``: a scratch state of ``space``)."""
    interpolate, get_x, get_y, get_yaw = space.interpolate, tmp.getX, tmp.getY, tmp.getYaw
    for k in range(1, m + 1):
        interpolate(a, b, k / m, tmp)
        rows.append((get_x(), get_y(), get_yaw()))


def _travel_backward(pts: np.ndarray):
    """Travel between consecutive planner states ``pts`` (K, 3) = (x, y, yaw): whether each step
    k -> k+1 goes backward (against the yaw at its middle), its yaw change [rad] and its
    length [m], each (K-1,)."""
    dyaw = (np.diff(pts[:, 2]) + math.pi) % (2.0 * math.pi) - math.pi
    mid = pts[:-1, 2] + 0.5 * dyaw
    d = np.diff(pts[:, :2], axis=0)
    backward = d[:, 0] * np.cos(mid) + d[:, 1] * np.sin(mid) < 0.0
    return backward, dyaw, np.hypot(d[:, 0], d[:, 1])


class _TrailerMotionValidator(ob.MotionValidator):
    """Motion check along OMPL's Reeds-Shepp curve at ``step`` metres: every sampled state
    valid; unless ``allow_pull_arcs``, no heading change while travelling backward; and, with
    ``pull_end_valid``, a free straight train at the end of every backward (pulling) run of the
    curve, located to 1e-6 of the curve by bisection (see :attr:`PlannerConfig.straight_pull_ends`).
    """

    def __init__(self, si, space, valid_many, step: float, allow_pull_arcs: bool,
                 pull_end_valid=None, pull_start_valid=None):
        super().__init__(si)
        self._space, self._valid_many, self._step = space, valid_many, float(step)
        self._allow = bool(allow_pull_arcs)
        self._pull_end_valid = pull_end_valid
        self._pull_start_valid = pull_start_valid
        self.goal: tuple[float, float] | None = None
        self._tmp = space.allocState()
        self._probe = space.allocState()

    def _backward_at(self, s1, s2, t: float, length: float) -> bool:
        """True if the curve s1 -> s2 travels backward just after the fraction ``t``."""
        dt = min(1e-7, 1e-7 / max(length, 1e-9)) if length > 0.0 else 1e-7
        a, b = self._tmp, self._probe
        self._space.interpolate(s1, s2, t, a)
        self._space.interpolate(s1, s2, min(t + dt, 1.0), b)
        yaw = a.getYaw()
        return (b.getX() - a.getX()) * math.cos(yaw) + (b.getY() - a.getY()) * math.sin(yaw) < 0.0

    def _pull_end_ok(self, s1, s2, t_lo: float, t_hi: float, length: float) -> bool:
        """Locate the end of a backward run in [t_lo, t_hi] (backward at t_lo, forward at t_hi)
        by bisection and check the straight train there."""
        for _ in range(40):
            if (t_hi - t_lo) * length < 1e-6:
                break
            mid = 0.5 * (t_lo + t_hi)
            if self._backward_at(s1, s2, mid, length):
                t_lo = mid
            else:
                t_hi = mid
        self._space.interpolate(s1, s2, t_hi, self._probe)
        p = self._probe
        return self._pull_end_valid(p.getX(), p.getY(), p.getYaw())

    def checkMotion(self, s1, s2):  # noqa: N802 (OMPL API)
        length = self._space.distance(s1, s2)
        if length <= 0.0:
            return bool(self._valid_many(np.array([[s2.getX(), s2.getY(), s2.getYaw()]])))
        m = max(1, int(math.ceil(length / self._step)))
        rows = [(s1.getX(), s1.getY(), s1.getYaw())]
        _sample_into(rows, self._space, s1, s2, m, self._tmp)
        pts = np.array(rows)
        # every sample's footprint at once (vectorized shapely); s1 is valid already
        if not self._valid_many(pts[1:]):
            return False
        # travel direction between consecutive samples: backward[k - 1] is sample k-1 -> k
        backward, dyaw, _ = _travel_backward(pts)
        if not self._allow and np.any(backward & (np.abs(dyaw) > 1e-9)):
            return False
        end_backward = False
        if self._pull_end_valid is not None:
            # a backward run ending between samples k - 1 and k + 1 (k = 1..m-1)
            for k in np.flatnonzero(backward[:-1] & ~backward[1:]) + 1:
                if not self._pull_end_ok(s1, s2, (k - 1) / m, (k + 1) / m, length):
                    return False
            # the sign of a whole interval misses a cusp close to either end of the curve:
            # compare with the exact direction there
            if self._backward_at(s1, s2, 0.0, length) and not backward[0]:
                if not self._pull_end_ok(s1, s2, 0.0, 1.0 / m, length):
                    return False
            end_backward = self._backward_at(s1, s2, max(0.0, 1.0 - 1e-6 / length), length)
            if backward[-1] and not end_backward:
                if not self._pull_end_ok(s1, s2, (m - 1) / m, 1.0, length):
                    return False
        if self._pull_start_valid is not None and backward[0]:
            # the curve starts pulling: its leading pull, samples 0..end
            forward = np.flatnonzero(~backward)
            end = int(forward[0]) if forward.size else m
            if not self._pull_start_valid(s1, pts[: end + 1]):
                return False
        if self._pull_end_valid is not None and end_backward and self._is_goal(s2):
            # the path ends pulling: at the goal the chain is drawn out straight
            return bool(self._pull_end_valid(s2.getX(), s2.getY(), s2.getYaw()))
        # A curve ending backward elsewhere may go on pulling in the next curve: that junction
        # is checked on the finished path (junction_pull_end_ok).
        return True

    def _is_goal(self, state) -> bool:
        g = self.goal
        return g is not None and abs(state.getX() - g[0]) < 1e-9 and abs(state.getY() - g[1]) < 1e-9

    def junction_pull_end_ok(self, a, b, c) -> bool:
        """True unless the curve ``a -> b`` ends backward, the next one ``b -> c`` starts
        forward, and the straight train at that cusp ``b`` is not free."""
        if self._pull_end_valid is None:
            return True
        la = self._space.distance(a, b)
        lb = self._space.distance(b, c)
        if la <= 0.0 or lb <= 0.0:
            return True
        ends_backward = self._backward_at(a, b, max(0.0, 1.0 - 1e-6 / la), la)
        starts_forward = not self._backward_at(b, c, 0.0, lb)
        if not (ends_backward and starts_forward):
            return True
        return bool(self._pull_end_valid(b.getX(), b.getY(), b.getYaw()))


@dataclass
class _Attempt:
    """State of one planning attempt (what the replanning loop changes)."""

    radius: float
    inflation: float
    blocks: list = field(default_factory=list)
    pull_start_tolerance: float | None = None


def _solve_once(world: World, train: Train, start_yaw, goal_yaw, config: PlannerConfig,
                attempt: _Attempt, solve_time: float, seed: int | None, start_headings=None,
                refine_time: float = 0.0, refine_below: float = math.inf):
    """One OMPL solve of the last trailer. Returns (states (M,3), info) or raises PlanningError.

    ``refine_time`` [s] > 0 shortens the simplified path further by a local search on its
    states (:func:`_local_search`) until it stops gaining or ``refine_time`` has passed, if
    the simplified path is shorter than ``refine_below`` [m]."""
    last = train.last
    planning_world = world.with_obstacles(attempt.blocks) if attempt.blocks else world
    region = planning_world.eroded(attempt.inflation + config.offtrack_allowance)
    contains = region.contains
    corners_of = last.corner_points

    def is_valid(state) -> bool:
        return bool(contains(Polygon(corners_of(state.getX(), state.getY(),
                                                state.getYaw() + math.pi))))

    def valid_many(pts: np.ndarray) -> bool:
        """Every (x, y, yaw) row's footprint inside the region."""
        polys = shapely.polygons(last.corners(pts[:, 0], pts[:, 1], pts[:, 2] + math.pi))
        return bool(shapely.contains(region, polys).all())

    if seed is not None:
        _set_seed(seed)
    space = _space(attempt.radius, world.bounds)
    ss = og.SimpleSetup(space)
    ss.setStateValidityChecker(is_valid)
    si = ss.getSpaceInformation()
    pull_end_valid = None
    if config.straight_pull_ends:
        # bodies 0..n-1 on the straight line ahead of the last trailer, at their link distances
        ahead = np.cumsum((train.geometry.front + train.geometry.rear)[::-1])[::-1]
        chain_region = planning_world.eroded(attempt.inflation)
        leading_bodies = train.bodies[:-1]

        def pull_end_valid(x, y, yaw):
            theta = yaw + math.pi
            c, s = math.cos(theta), math.sin(theta)
            return all(chain_region.contains(Polygon(body.corner_points(x + d * c, y + d * s, theta)))
                       for body, d in zip(leading_bodies, ahead))

    pull_start_valid = None
    if attempt.pull_start_tolerance is not None:
        tolerance = float(attempt.pull_start_tolerance)
        start_xy = (float(start_yaw[0]), float(start_yaw[1]))

        def pull_start_valid(s1, samples):
            pts = np.column_stack((samples[:, :2], samples[:, 2] + math.pi))
            at_start = math.hypot(s1.getX() - start_xy[0], s1.getY() - start_xy[1]) < 1e-9
            target = start_headings if at_start else None
            return straight_chain_mismatch(train.geometry, pts, target) <= tolerance

    validator = _TrailerMotionValidator(si, space, valid_many, config.planning_resolution,
                                        config.allow_pull_arcs, pull_end_valid, pull_start_valid)
    si.setMotionValidator(validator)
    validator.goal = (float(goal_yaw[0]), float(goal_yaw[1]))
    start, goal = space.allocState(), space.allocState()
    for state, pose in ((start, start_yaw), (goal, goal_yaw)):
        state.setX(float(pose[0]))
        state.setY(float(pose[1]))
        state.setYaw(_yaw_wrap(pose[2]))
    ss.setStartAndGoalStates(start, goal)
    if config.planner in _OPTIMIZING:
        ss.setOptimizationObjective(ob.PathLengthOptimizationObjective(si))
    planner = _allocate_planner(config.planner, si)
    if config.planner == "rrtconnect":
        planner.setRange(config.extension_for(attempt.radius))
    ss.setPlanner(planner)
    ss.setup()
    t0 = time.perf_counter()
    if si.isValid(start) and si.isValid(goal) and si.checkMotion(start, goal):
        # The shortest Reeds-Shepp curve itself is free: it is the optimal path.
        info = {"status": "direct", "solve_time": time.perf_counter() - t0,
                "planner_time": time.perf_counter() - t0}
        states = np.array([[p.getX(), p.getY(), p.getYaw()] for p in (start, goal)])
        info["raw_length"] = info["length_ompl"] = float(space.distance(start, goal))
        return states, info
    status = ss.solve(float(solve_time))
    solve_wall = time.perf_counter() - t0
    name = str(status)
    info = {"status": name, "solve_time": solve_wall, "planner_time": ss.getLastPlanComputationTime()}
    if not ss.haveExactSolutionPath():
        if ss.haveSolutionPath():
            path = ss.getSolutionPath()
            reached = path.getState(path.getStateCount() - 1)
            gap = float(space.distance(reached, goal))
            raise PlanningError(
                "approximate_only",
                f"{config.planner} found only an approximate solution within {solve_time:.3g} s: "
                f"it ends at ({reached.getX():.3f}, {reached.getY():.3f}), {gap:.3f} m (Reeds-Shepp) "
                f"from the goal ({goal_yaw[0]:.3f}, {goal_yaw[1]:.3f})",
                where=(reached.getX(), reached.getY()), details={"gap": gap, **info},
            )
        raise PlanningError(
            "unreachable",
            f"{config.planner} found no path to the goal ({goal_yaw[0]:.3f}, {goal_yaw[1]:.3f}) "
            f"within {solve_time:.3g} s (status {name})",
            where=tuple(goal_yaw[:2]), details=info,
        )
    path = ss.getSolutionPath()
    info["raw_length"] = float(path.length())
    if config.simplify:
        t1 = time.perf_counter()
        # OMPL's reduceVertices, then the greedy shortcut; OMPL's simplifyMax (to its fixed
        # point) takes 40-100 ms on the bay, 5-10 times the solve, for 2-3 % shorter paths
        og.PathSimplifier(si).reduceVertices(path)
        path = _greedy_shortcut(si, path)
        info["simplify_time"] = time.perf_counter() - t1
    if refine_time > 0.0 and path.length() < refine_below:
        t1 = time.perf_counter()
        path = _local_search(si, space, validator, path, refine_time,
                             np.random.default_rng(seed))
        info["refine_time"] = time.perf_counter() - t1
    path_states = list(path.getStates())
    repaired, blocked = _repair_pull_ends(si, space, validator, path_states,
                                          0 if seed is None else int(seed))
    info["pull_end_repairs"] = repaired
    if blocked is not None:
        raise PlanningError(
            "pull_end_blocked",
            f"{config.planner}'s path ends a pull at ({blocked[0]:.3f}, {blocked[1]:.3f}), where "
            "the train drawn out straight ahead of the last trailer does not fit, and no "
            "nearby cusp does",
            where=blocked, details=info,
        )
    if attempt.pull_start_tolerance is not None:
        bad = _pull_start_outside(space, path_states, train, attempt.pull_start_tolerance,
                                  start_headings)
        if bad is not None:
            raise PlanningError(
                "pull_start_mismatch",
                f"{config.planner}'s path starts a pull at ({bad[0]:.3f}, {bad[1]:.3f}) that "
                f"needs a chain {bad[2]:.3f} m from the one it starts from (allowed "
                f"{attempt.pull_start_tolerance:.3g} m)",
                where=bad[:2], details=info,
            )
    states = np.array([[s.getX(), s.getY(), s.getYaw()] for s in path_states])
    info["length_ompl"] = float(sum(space.distance(a, b)
                                    for a, b in zip(path_states[:-1], path_states[1:])))
    return states, info


def _solve_restarts(world: World, train: Train, start_yaw, goal_yaw, config: PlannerConfig,
                    attempt: _Attempt, solve_time: float, seed: int | None, start_headings=None):
    """Anytime planning by restarts: RRTConnect, simplification and a local search on the
    path's states (:func:`_local_search`, until it stops gaining) again and again, each with its
    own seed (derived from ``seed``), for ``solve_time`` seconds; the shortest path wins.

    Not asymptotically optimal like RRT* or BIT*, but each restart is a complete, locally
    shortest path within about 0.1 s, which in corridors beats the optimizing planners at
    short budgets (``benchmarks/bench_planner.py``). At least one restart runs to its end.
    Returns (states, info) of the shortest; raises the last PlanningError if none succeeded.
    """
    t0 = time.perf_counter()
    single = replace(config, planner="rrtconnect")
    rng = np.random.default_rng(seed)
    best, runs, first_time, last_error = None, 0, None, None
    while True:
        remaining = solve_time - (time.perf_counter() - t0)
        if runs and remaining <= 0.0:
            break
        # the first restart is RRTConnect with ``seed`` itself, so the result is never longer
        # than the default planner's path for the same seed
        run_seed = seed if (seed is None or runs == 0) else int(rng.integers(1, 2**31 - 1))
        try:
            # the local search gains 5-15 %: a restart far longer than the best so far is
            # not worth it
            below = math.inf if best is None else _REFINE_RATIO * best[1]["length_ompl"]
            states, info = _solve_once(world, train, start_yaw, goal_yaw, single, attempt,
                                       max(remaining, 1e-3), run_seed, start_headings,
                                       refine_time=max(remaining, 1e-3), refine_below=below)
        except PlanningError as exc:
            last_error = exc
        else:
            if first_time is None:
                first_time = time.perf_counter() - t0
            if best is None or info["length_ompl"] < best[1]["length_ompl"]:
                best = (states, info)
        runs += 1
    if best is None:
        raise last_error
    states, info = best
    info = {**info, "restarts": runs, "planner_time": first_time,
            "solve_time": time.perf_counter() - t0}
    return states, info


def _pull_start_outside(space, states: list, train: Train, tolerance: float, start_headings,
                        step: float = 0.02):
    """The first pull of the path (a whole run over any number of local curves) that starts
    farther than ``tolerance`` from the chain it needs, as (x, y, mismatch), or None.

    The motion validator checks the part of a pull inside one local curve; this checks whole
    runs on the finished path, sampled every ``step`` metres. The chain a run starts from is
    ``start_headings`` at the start (None: straight) and a straight chain after a cusp."""
    tmp = space.allocState()
    rows = [(states[0].getX(), states[0].getY(), states[0].getYaw())]
    for a, b in zip(states[:-1], states[1:]):
        _sample_into(rows, space, a, b, max(1, int(math.ceil(space.distance(a, b) / step))), tmp)
    pts = np.array(rows)
    if pts.shape[0] < 2:
        return None
    backward, _, step_length = _travel_backward(pts)
    backward &= step_length > 1e-12
    edges = np.diff(np.concatenate(([0], backward.astype(int), [0])))
    for i0, i1 in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)):
        run = pts[i0:i1 + 1]
        chain = np.column_stack((run[:, :2], run[:, 2] + math.pi))
        target = start_headings if i0 == 0 else None
        mismatch = straight_chain_mismatch(train.geometry, chain, target)
        if mismatch > tolerance:
            return float(run[0, 0]), float(run[0, 1]), mismatch
    return None


def _near(space, state, rng, sigma_xy: float, sigma_yaw: float):
    """A new state at a Gaussian distance from ``state`` (sigmas in m and rad)."""
    cand = space.allocState()
    cand.setX(state.getX() + sigma_xy * rng.standard_normal())
    cand.setY(state.getY() + sigma_xy * rng.standard_normal())
    cand.setYaw(_yaw_wrap(state.getYaw() + sigma_yaw * rng.standard_normal()))
    return cand


def _fits(si, validator, states: list, i: int, middle: list) -> bool:
    """``states[i - 1] -> middle... -> states[i + 1]`` (in place of ``states[i]``) is free, and
    the pull-end rule holds at every junction it touches."""
    seq = [states[i - 1], *middle, states[i + 1]]
    if not all(si.checkMotion(a, b) for a, b in zip(seq[:-1], seq[1:])):
        return False
    seq = states[max(0, i - 2):i - 1] + seq + states[i + 2:i + 3]
    return all(validator.junction_pull_end_ok(a, b, c)
               for a, b, c in zip(seq[:-2], seq[1:-1], seq[2:]))


def _repair_pull_ends(si, space, validator, states: list, seed: int, tries: int = 40):
    """Move every cusp of the path where a pull ends with a blocked straight train.

    The motion validator checks the straight train at pull ends inside a local curve; a pull
    that ends exactly at a state between two curves is only seen here. Each such state is
    dropped if its neighbours connect directly, else replaced by the first of ``tries``
    random states near it (0.25 m, 0.35 rad; numpy generator seeded with ``seed``) whose two
    curves are free and whose own and neighbouring junctions pass. ``states`` is edited in
    place. Returns (number of repairs, (x, y) of a junction that could not be repaired or
    None).
    """
    rng = np.random.default_rng(seed)
    repairs, i = 0, 1
    while i < len(states) - 1:
        b = states[i]
        if validator.junction_pull_end_ok(states[i - 1], b, states[i + 1]):
            i += 1
            continue
        if _fits(si, validator, states, i, []):
            del states[i]
            repairs += 1
            continue
        found = None
        for _ in range(tries):
            cand = _near(space, b, rng, 0.25, 0.35)
            if si.isValid(cand) and _fits(si, validator, states, i, [cand]):
                found = cand
                break
        if found is None:
            return repairs, (b.getX(), b.getY())
        states[i] = found
        repairs += 1
        i += 1
    return repairs, None


def _local_search(si, space, validator, path, budget: float, rng, sigma=(0.3, 0.3)):
    """Shorten ``path`` by moving one interior state at a time: Gaussian proposals (``sigma``
    in x and y [m] and yaw [rad], halved after 30 proposals in a row without a gain), accepted
    when the path gets shorter, both adjacent curves are free and the pull-end rule holds at
    the moved state and its neighbours; for ``budget`` seconds."""
    t0 = time.perf_counter()
    states = list(path.getStates())
    scale, misses = 1.0, 0
    while len(states) > 2 and time.perf_counter() - t0 < budget and scale > 0.01:
        i = int(rng.integers(1, len(states) - 1))
        a, b, c = states[i - 1], states[i], states[i + 1]
        old = space.distance(a, b) + space.distance(b, c)
        cand = _near(space, b, rng, scale * sigma[0], scale * sigma[1])
        new = space.distance(a, cand) + space.distance(cand, c)
        if new < old - 1e-6 and si.isValid(cand) and _fits(si, validator, states, i, [cand]):
            states[i] = cand
            misses = 0
        else:
            misses += 1
            if misses >= 30:
                scale, misses = 0.5 * scale, 0
    out = og.PathGeometric(si, states[0])
    for st in states[1:]:
        out.append(st)
    return _greedy_shortcut(si, out)


def _greedy_shortcut(si, path):
    """Deterministic shortcut: from each kept state, jump to the farthest later state that a
    single free Reeds-Shepp curve reaches (removes the wiggles random shortcutting leaves)."""
    states = list(path.getStates())
    kept, i = [states[0]], 0
    while i < len(states) - 1:
        j = len(states) - 1
        while j > i + 1 and not si.checkMotion(states[i], states[j]):
            j -= 1
        kept.append(states[j])
        i = j
    return og.PathGeometric(si, kept)


def _segments_from_states(states: np.ndarray, rho: float) -> tuple[list[Segment], float]:
    """Line/arc segments of the Reeds-Shepp path through ``states`` (planner frame), and the
    largest deviation [m] between the segments and OMPL's interpolation (checked at 33 points
    per local curve)."""
    from .reeds_shepp import evaluate_primitives

    prims: list[Primitive] = []
    worst = 0.0
    for a, b in zip(states[:-1], states[1:]):
        curve = ReedsSheppCurve(rho, a, b)
        p = curve.primitives()
        if curve.length > 0.0 and p:
            ts = np.linspace(0.0, 1.0, 33)
            ref = np.array([curve.interpolate(t) for t in ts])
            ev = evaluate_primitives(a, p, rho, ts * curve.length)
            worst = max(worst, float(np.hypot(*(ev[:, :2] - ref[:, :2]).T).max()))
        prims += p
    return _merge(primitives_to_segments(prims, rho)), worst


def _chain_to_yaw(pose) -> tuple[float, float, float]:
    return float(pose[0]), float(pose[1]), float(pose[2]) + math.pi


def _check_endpoints(world: World, train: Train, start, goal, start_headings, inflation: float):
    """Raise PlanningError for no free space, colliding start/goal, or separated start/goal."""
    if world.free.is_empty or world.free_area <= 1e-12:
        raise PlanningError(
            "no_free_space",
            f"the map has no free space (free area {world.free_area:.3g} m² inside outline bounds "
            f"{tuple(round(b, 3) for b in world.outline.bounds)})",
        )
    last = train.last
    half = 0.5 * min(last.length, last.width) + inflation
    core = world.eroded(half)
    if core.is_empty:
        raise PlanningError(
            "no_free_space",
            f"no place in the map fits the last trailer ({last.length} m x {last.width} m) with "
            f"{inflation} m clearance: the free space is nowhere wider than {2 * half:.3f} m",
        )
    region = world.eroded(inflation)
    theta0 = (np.full(train.n + 1, float(start[2])) if start_headings is None
              else np.asarray(start_headings, dtype=float))

    x, y = body_positions_along(np.asarray(start, dtype=float)[None, :], theta0[None, :], train.geometry)
    for i, body in enumerate(train.bodies):
        poly = body.polygons(x[0, i], y[0, i], theta0[i])
        if not region.contains(poly):
            name = "robot" if i == 0 else f"trailer {i}"
            raise PlanningError(
                "start_in_collision",
                f"at the start the {name} (body {i}) at ({x[0, i]:.3f}, {y[0, i]:.3f}), heading "
                f"{math.degrees(theta0[i]):.1f} deg, is not inside the free space with "
                f"{inflation} m clearance",
                where=(x[0, i], y[0, i], theta0[i]), details={"body": i},
            )
    if not region.contains(last.polygons(*goal)):
        raise PlanningError(
            "goal_in_collision",
            f"at the goal the last trailer at ({goal[0]:.3f}, {goal[1]:.3f}), heading "
            f"{math.degrees(goal[2]):.1f} deg, is not inside the free space with {inflation} m "
            "clearance",
            where=tuple(goal), details={"body": train.n},
        )
    # Footprint centres must lie in the free space shrunk by half the smaller side: if start and
    # goal centres are in different pieces of it, no motion connects them.
    pieces = list(getattr(core, "geoms", [core]))
    if len(pieces) > 1:
        def piece_of(pose):
            cx = pose[0] + last.offset * math.cos(pose[2])
            cy = pose[1] + last.offset * math.sin(pose[2])
            p = Point(cx, cy)
            return next((k for k, g in enumerate(pieces) if g.covers(p)), None)

        ka, kb = piece_of(start), piece_of(goal)
        if ka is not None and kb is not None and ka != kb:
            raise PlanningError(
                "unreachable",
                f"the goal ({goal[0]:.3f}, {goal[1]:.3f}) lies in a part of the map the last trailer "
                f"cannot reach from the start ({start[0]:.3f}, {start[1]:.3f}): every connection is "
                f"narrower than {2 * half:.3f} m (trailer width + 2 x clearance)",
                where=tuple(goal[:2]), details={"start_piece": ka, "goal_piece": kb},
            )


def plan(
    world: World,
    start: Sequence[float],
    goal: Sequence[float],
    train: Train,
    config: PlannerConfig | None = None,
    start_headings: Sequence[float] | None = None,
) -> PlannedPath:
    """Plan a line/arc path of the last trailer from ``start`` to ``goal`` and check the train.

    Parameters
    ----------
    world : World
    start, goal : (x, y, theta)
        Last trailer's axle-midpoint poses [m, m, rad], chain convention (theta toward the
        robot).
    train : Train
    config : PlannerConfig or None
    start_headings : (n+1,) or None
        Headings [rad] of robot and trailers at the start; None is a straight chain.

    Returns
    -------
    PlannedPath
        With :attr:`~PlannedPath.headings` from the whole-train check.

    Raises
    ------
    PlanningError
        ``reason`` in no_free_space, start_in_collision, goal_in_collision, unreachable,
        approximate_only, train_check_failed (PlanningInputError for malformed input).
    """
    config = config or PlannerConfig()
    t_begin = time.perf_counter()
    start = np.asarray(start, dtype=float).reshape(-1)
    goal = np.asarray(goal, dtype=float).reshape(-1)
    for name, pose in (("start", start), ("goal", goal)):
        if pose.size != 3 or not np.all(np.isfinite(pose)):
            raise PlanningInputError(f"{name} = {pose.tolist()!r}: need finite (x, y, theta)")
    if start_headings is not None:
        start_headings = np.asarray(start_headings, dtype=float).reshape(-1)
        if start_headings.size != train.n + 1 or not np.all(np.isfinite(start_headings)):
            raise PlanningInputError(
                f"start_headings has {start_headings.size} entries; need n + 1 = {train.n + 1} "
                "finite headings [rad]"
            )
        if abs(math.remainder(start_headings[-1] - start[2], 2 * math.pi)) > 1e-9:
            raise PlanningInputError(
                f"start_headings[-1] = {start_headings[-1]!r} differs from start theta {start[2]!r}"
            )
    _check_endpoints(world, train, start, goal, start_headings, config.inflation)

    tracker = config.tracker()
    tracker.controller_for(train.geometry)  # a controller for another n fails here, not later
    initial = _Attempt(config.radius_for(train), config.inflation,
                       pull_start_tolerance=config.pull_start_tolerance)
    attempt = initial
    history = []
    last_error: PlanningError | None = None
    last_result = None
    for k in range(int(config.max_attempts)):
        remaining = config.time_budget - (time.perf_counter() - t_begin)
        if remaining <= 0.0:
            break
        if config.planner in _ANYTIME:
            solve_time = min(config.anytime_time, remaining)
        else:
            # a replan may find nothing (e.g. a block closed the corridor): it gets half of
            # what is left, so that another try remains
            solve_time = remaining if k == 0 else 0.5 * remaining
        seed = None if config.seed is None else int(config.seed) + k
        try:
            solve = _solve_restarts if config.planner == "restarts" else _solve_once
            states, info = solve(world, train, _chain_to_yaw(start), _chain_to_yaw(goal),
                                 config, attempt, solve_time, seed, start_headings)
        except PlanningError as exc:
            last_error = exc
            history.append({"attempt": k, "radius": attempt.radius, "inflation": attempt.inflation,
                            "blocks": len(attempt.blocks), "error": exc.reason})
            if exc.reason in ("pull_end_blocked", "pull_start_mismatch"):
                continue  # a rule of the planner's own, not of the train check: next seed
            if k == 0 or exc.reason not in ("unreachable", "approximate_only"):
                break
            # a replanning change made the goal unreachable: undo the changes, try a new seed
            attempt = replace(initial)
            continue
        segments, deviation = _segments_from_states(states, attempt.radius)
        if deviation > 1e-6:
            raise RuntimeError(
                f"Reeds-Shepp segment recovery deviates {deviation:.3g} m from OMPL's curve"
            )
        entry = {"attempt": k, "radius": attempt.radius, "inflation": attempt.inflation,
                 "blocks": len(attempt.blocks), "seed": seed, **info}
        result = None
        if config.check_train:
            result = check_train(world, train, start, segments, start_headings,
                                 margin=config.inflation, resolution=config.check_resolution,
                                 tracker=tracker)
            entry["train_ok"] = result.ok
            entry["failure"] = result.failure
        history.append(entry)
        if result is None or result.ok:
            info_all = {
                "planner": config.planner, "seed": config.seed, "attempts": history,
                "radius": attempt.radius, "inflation": attempt.inflation,
                "time": time.perf_counter() - t_begin,
                "first_solution_time": history[0].get("planner_time"),
                "train_check": None if result is None else {
                    "max_abs_phi": result.max_abs_phi.tolist(),
                    "min_clearance": result.min_clearance,
                    "max_tracking_error": result.max_tracking_error,
                    "max_lateral_error": result.max_lateral_error,
                    "max_heading_error": result.max_heading_error,
                    "goal_error": list(result.goal_error),
                    "speed": tracker.speed, "cusp_dwell": tracker.cusp_dwell,
                },
            }
            path = PlannedPath(start, tuple(segments), attempt.radius,
                               start_headings,
                               config.check_resolution, info_all)
            if result is not None:
                path.headings = _resample_headings(result, path, tracker)
            log.info("planned %.2f m, %d segments, %d cusps in %.3f s (%d attempts)",
                     path.length, len(segments), path.n_cusps, info_all["time"], k + 1)
            return path
        last_result = result
        attempt = _next_attempt(attempt, result.failure, train, config, segments)
        # never block the last trailer's own start or goal footprint
        keep_clear = [train.last.polygons(*pose).buffer(attempt.inflation + config.offtrack_allowance)
                      for pose in (start, goal)]
        attempt.blocks = [b for b in attempt.blocks if not any(b.intersects(k) for k in keep_clear)]
    if last_result is not None and last_result.failure is not None:
        f = last_result.failure
        name = "robot" if f["body"] == 0 else f"trailer {f['body']}"
        if f["kind"] == "collision":
            what = f"collides near ({f['x']:.3f}, {f['y']:.3f})"
        elif f["kind"] == "joint_limit":
            what = (f"reaches |phi_{f['body']}| = {math.degrees(abs(f['phi'])):.1f} deg > "
                    f"{math.degrees(train.phi_max):.1f} deg")
        else:
            what = (f"ends {f['distance']:.3f} m and {math.degrees(f['heading_error']):.1f} deg "
                    f"from the goal (at ({f['x']:.3f}, {f['y']:.3f}))")
        raise PlanningError(
            "train_check_failed",
            f"after {len(history)} attempts ({time.perf_counter() - t_begin:.2f} s) the whole train "
            f"still fails: the {name} {what} at t = {f['t']:.2f} s, s = {f['s']:.2f} m of the "
            "last plan",
            where=(f["x"], f["y"]), details={"failure": f, "attempts": history},
        )
    if last_error is not None:
        last_error.details.setdefault("attempts", history)
        raise last_error
    raise PlanningError(
        "unreachable",
        f"no plan within the time budget {config.time_budget} s",
        where=tuple(goal[:2]), details={"attempts": history},
    )


def _resample_headings(result, path: PlannedPath, tracker: TrackerConfig) -> np.ndarray:
    """The closed-loop simulation's headings at the times the reference passes the path's dense
    samples (at a cusp: when it arrives there). They belong to the simulated train, whose last
    trailer is near, not exactly at, :attr:`PlannedPath.poses`."""
    t, _ = reference_times(path.segments, tracker.speed, tracker.cusp_dwell, path.s)
    return result.headings_at(t)


def _next_attempt(attempt: _Attempt, failure: dict, train: Train, config: PlannerConfig,
                  segments: Sequence[Segment] = ()) -> _Attempt:
    """Change what the last failure of the closed-loop train check calls for.

    - A leading body (robot or trailer 1..n-1) collides while pulling: a larger radius. The
      robot leads on its own reference (:class:`~pushtrain.core.pulling.PullGuide`), which
      swings wide of the last trailer's path where the pull turns; the last trailer never
      goes there, so blocking the spot changes nothing, while a larger radius narrows the
      swing.
    - Any other collision: block the colliding region (and grow the inflation from the
      second block on). If a pull of the plan (``segments``) came before it, also halve the
      pull-start tolerance: what the chain cannot make up while pulling, the last trailer
      carries into the push after the cusp.
    - A joint-limit failure or a missed goal: a larger radius.
    """
    from shapely.geometry import box as _box

    if failure["kind"] == "collision" and not (failure["direction"] == PULL
                                               and failure["body"] < train.n):
        r = config.block_radius
        block = _box(failure["x"] - r, failure["y"] - r, failure["x"] + r, failure["y"] + r)
        blocks = attempt.blocks + [block]
        inflation = attempt.inflation + (config.inflation_growth if len(blocks) > 1 else 0.0)
        tolerance = attempt.pull_start_tolerance
        pos, pulled = 0.0, False
        for seg in segments:
            if pos >= failure["s"]:
                break
            pulled = pulled or seg.direction == PULL
            pos += seg.length
        if pulled and tolerance is not None:
            tolerance *= 0.5
        log.info("train check: %s; blocking (%.2f, %.2f), inflation %.3f m, pull-start "
                 "tolerance %s m", failure["kind"], failure["x"], failure["y"], inflation,
                 tolerance)
        return replace(attempt, inflation=inflation, blocks=blocks, pull_start_tolerance=tolerance)
    radius = attempt.radius * config.radius_growth
    log.info("train check: %s of body %d while %s; radius %.3f m", failure["kind"],
             failure["body"], "pulling" if failure["direction"] == PULL else "pushing", radius)
    return replace(attempt, radius=radius)
