"""Planner settings: :class:`PlannerConfig`, the planner names and the turning-radius rule.

Turning-radius rule (when :attr:`PlannerConfig.turning_radius` is None)::

    r = D / tan(phi_max / (2 (1 + transient_margin)))      D = max_i max(F_i, R_i)

i.e. the steady joint angle on the arc, 2 atan(D / r), is phi_max / (1 + transient_margin).
Entering an arc from a line does not overshoot the steady angle in the chain kinematics, but
switching between opposite arcs does: up to 1.46x the steady angle for 3 trailers and 1.56x for
10 (r = 0.9 .. 1.5 m, D = 0.52 m), so the default margin 0.6 covers both; tracking transients
of the closed loop need the rest. With phi_max = 90 deg and D = 0.52 m this gives r = 0.975 m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Literal

import numpy as np
from pydantic import Field

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.kinematics import ChainGeometry
from pushtrain.defaults import (
    CUSP_DWELL,
    GOAL_TOLERANCE,
    REFERENCE_SPEED,
    ROLLOUT_SETTLE_TIME,
    ROLLOUT_STEP,
)
from pushtrain.errors import PlanningInputError
from pushtrain.settings import angle_setting, setting
from pushtrain.validation import NonNegFloat, PositiveFloat

from .budget import (
    DEFAULT_SEARCH_SECONDS,
    DEFAULT_WALL_CAP,
    OMPL_DEFAULT_SECONDS,
    checks_for,
    default_steps,
    steps_for,
)
from .train import Train

__all__ = ["PLANNERS", "PlannerConfig", "TrackerConfig", "turning_radius_from_joint_limit",
           "ANYTIME_PLANNERS", "OPTIMIZING_PLANNERS"]

PLANNERS = ("lattice", "rrtconnect", "restarts", "rrtstar", "bitstar", "prmstar")
"""Planner names: ``lattice`` (the default) searches closed-loop states of the whole train
(:mod:`~pushtrain.planner.lattice`); the others plan the last trailer with OMPL and check the
train afterwards: ``rrtconnect`` stops at its first solution, the rest are anytime optimal."""

ANYTIME_PLANNERS = {"restarts", "rrtstar", "bitstar", "prmstar"}
OPTIMIZING_PLANNERS = {"rrtstar", "bitstar", "prmstar"}  # OMPL planners given a length objective


def turning_radius_from_joint_limit(
    phi_max: float, link: float, transient_margin: float = 0.6
) -> float:
    """Turning radius [m] whose steady joint angle is ``phi_max / (1 + transient_margin)``.

    ``r = link / tan(phi_max / (2 (1 + transient_margin)))`` with ``phi_max`` [rad] in (0, pi)
    and ``link`` the largest hitch link [m].
    """
    if not (0.0 < phi_max < math.pi):
        raise PlanningInputError(f"phi_max = {phi_max!r} rad: allowed is (0, pi)")
    if not (transient_margin >= 0.0 and math.isfinite(transient_margin)):
        raise PlanningInputError(
            f"transient_margin = {transient_margin!r}: must be finite and >= 0"
        )
    return float(link / math.tan(phi_max / (2.0 * (1.0 + transient_margin))))


@dataclass(frozen=True)
class TrackerConfig:
    """How the co-simulation will track the plan: what the planner's closed loop on the engine
    (:mod:`pushtrain.core.engine`) simulates in the search and in
    :func:`~pushtrain.planner.train_check.check_train`.

    Parameters
    ----------
    controller : ControllerConfig or None
        The co-simulation's controller; None: :class:`~pushtrain.core.controller.ControllerConfig`'s
        defaults (the scenario's) with the train's geometry as its chain model.
    speed : float
        Reference speed |v_d| [m/s] on every segment without its own speed, > 0.
    cusp_dwell : float
        Rest [s] of the reference at every direction change, >= 0.
    step : float
        Control and integration step [s], > 0 (the controller is called every ``step``, its
        command held over the step, RK4 of the kinematic chain with the train's own geometry,
        no velocity lag, no slip). The error is that of the zero-order hold, first order in the
        step: on a bay plan with a cusp and 0.24 m transients (3 trailers) the last trailer's
        trajectory differs from a 0.002 s run by 2.4 cm with a 0.1 s step, 1.0 cm with 0.05 s
        and 0.36 cm with the default 0.025 s (:data:`pushtrain.defaults.ROLLOUT_STEP`; a test
        keeps it below 1 cm).
    settle_time : float
        Simulated time [s] past the reference's end, >= 0 (the reference then rests and the
        robot brakes to a stop within its acceleration limit;
        :data:`pushtrain.defaults.ROLLOUT_SETTLE_TIME`).
    goal_tolerance : (float, float) or None
        Position [m] and heading [rad] tolerance of the last trailer at the end of the run
        (the co-simulation's goal test); None: report the goal error only.
    """

    controller: ControllerConfig | None = None
    speed: float = REFERENCE_SPEED
    cusp_dwell: float = CUSP_DWELL
    step: float = ROLLOUT_STEP
    settle_time: float = ROLLOUT_SETTLE_TIME
    goal_tolerance: tuple[float, float] | None = GOAL_TOLERANCE

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
        config = (self.controller if self.controller is not None
                  else ControllerConfig(geometry=geometry))
        if config.geometry.n != geometry.n:
            raise PlanningInputError(
                f"tracker.controller has a chain model of n = {config.geometry.n} trailers; the "
                f"train has n = {geometry.n}")
        return config


@dataclass(frozen=True)
class PlannerConfig:
    """Planner settings (SI units).

    The fields declared with :func:`~pushtrain.settings.setting` are the scenario's
    ``[planner]`` section (an angle as ``NAME_deg``, in degrees), generated from these
    declarations: the file's default is the field's default.

    Parameters
    ----------
    turning_radius : float or None
        Reeds-Shepp radius [m]; None derives it from the train's ``phi_max`` with
        :func:`turning_radius_from_joint_limit` and ``transient_margin``.
    transient_margin : float
        Margin of the radius rule (0.6: steady joint angle = phi_max / 1.6).
    planner : str
        One of :data:`PLANNERS`. ``lattice`` (default): the whole-train closed-loop search
        (:func:`~pushtrain.planner.whole_train.plan_lattice`); its settings are ``clearance``,
        ``goal_tolerance``, ``joint_margin``, ``pull_max_phi``, ``step_length``,
        ``search_weight``, ``sample_spacing``, ``smooth`` and ``time_budget``. The OMPL
        planners of the last trailer: ``rrtconnect`` returns its first solution fast,
        the others improve the path for ``anytime_time``: ``restarts`` repeats
        RRTConnect, simplification and a local search on the path's states with new seeds and
        keeps the shortest; ``rrtstar``,
        ``bitstar`` and ``prmstar`` are OMPL's asymptotically optimal planners.
    time_budget : float or None
        Budget [s] of planning and all replanning together, counted as work, not read from
        the clock (:mod:`~pushtrain.planner.budget`). None (the default): for ``lattice``
        about 20 s of CPU whatever n (:func:`~pushtrain.planner.budget.default_steps`: 2.9
        million simulated control steps for three trailers); the search stops at its first
        plan, so this only bounds a search that finds none. For the OMPL planners None is 1 s.
        Given: for ``lattice`` 150 000 simulated control steps per second; for the OMPL
        planners 1000 motion checks per second (the validation of one local Reeds-Shepp
        curve, about 1 ms on a current laptop core; BIT*: 500, as its other work grows after
        its first solution), and each whole-train check counts one motion check per 10
        simulated control steps (a 10 m plan at 0.08 m/s: about 500). The first attempt of
        ``rrtconnect`` may use all of it, each replan half of what is left. 2 s = 2000
        checks. PRM* alone stops on the clock after its budget's seconds (OMPL checks its
        termination on a second thread).
    anytime_time : float
        Budget [s] of one anytime-planner run, converted like ``time_budget`` (0.5 s = 500
        motion checks; a restart takes 100-300 in the bay and the L-corridors) and capped by
        what is left of ``time_budget``.
    seed : int or None
        OMPL random seed (>= 1). Same seed, same plan, on any machine and under any load,
        since budgets count work (``prmstar`` excepted: OMPL's PRM looks for a solution on a
        second thread while it grows the roadmap). None: OMPL's own seed. OMPL's seed is
        process-wide: plans in threads take turns for their OMPL calls.
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
        :func:`~pushtrain.planner.planner._next_attempt`).
    check_train : bool
        Run the whole-train check (disable only to study the last trailer alone): a
        closed-loop simulation of the co-simulation's controller along the plan
        (:func:`~pushtrain.planner.train_check.check_train`).
    allow_pull_arcs : bool
        Let local Reeds-Shepp curves turn while pulling (default). False restricts pulling to
        straight lines (much harder for the sampling planners; for studies only).
    controller : ControllerConfig or None
        The co-simulation's controller, simulated by the whole-train check
        (:class:`TrackerConfig`); None: the scenario defaults with the train's chain model.
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
        (``PlanningError`` reason ``pull_end_blocked`` if none is left). Without it the
        sampling planner ends pulls on arcs whose tangent points into a wall (bay, seeds 1-20:
        0 first plans passed the closed-loop check).
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
    clearance : float or sequence of float
        ``lattice``: the distance [m] every body keeps from the walls, one value or one per
        body (robot first, then trailers 1..n), >= 0. 0.05 m lets a 0.6 m wide trailer into a
        0.9 m bay with 0.1 m left for tracking.
    goal_tolerance : (float, float)
        ``lattice``: position [m] and heading [rad] tolerance of the simulated last trailer at
        the goal (the co-simulation's goal test; the scenario's ``sim.goal_tolerance``).
    goal_fraction : float
        ``lattice``: the planner's prediction must end within this fraction (0, 1] of
        ``goal_tolerance``; the rest is left to the difference between the kinematic
        prediction and the co-simulated FMU (about 1-2 cm).
    joint_margin : float
        ``lattice``: the search keeps every |phi_i| <= phi_max - joint_margin [rad] (the
        co-simulation's joints differ from the kinematic prediction by a few degrees).
    pull_max_phi : float
        ``lattice``: a pull may start only when every |phi_i| <= pull_max_phi [rad] (the chain
        nearly straight, as a driver would pull).
    step_length : float
        ``lattice``: length [m] of one search primitive.
    search_weight : float
        ``lattice``: weight (>= 1) of the heuristic; larger searches faster, less optimally.
    sample_spacing : float
        ``lattice``: largest distance [m] between the sampled points of a body's outline in
        the distance-field test (conservative by half of it).
    smooth : bool
        ``lattice``: try Reeds-Shepp shortcuts on the found path (fewer turns, shorter).
    goal_max_phi : float or None
        ``lattice``: the goal also needs every |phi_i| <= goal_max_phi [rad] when the last trailer
        arrives (the whole train straight behind it, e.g. parked in a slot); None: any chain.
    anytime : bool
        ``lattice``: search on after the first path until ``time_budget`` is spent and keep
        the cheapest (length, turning and cusps priced as the search prices them); False
        (default): return the first path.
    time_cap : float or None
        Wall-clock safety cap [s] of one :func:`~pushtrain.planner.planner.plan` call; None:
        10 x the budget's seconds + 10 s for an explicit ``time_budget``, and
        :data:`~pushtrain.planner.budget.DEFAULT_WALL_CAP` (50 s) for the default budget, so
        that no run at the defaults keeps a user waiting past a minute. Only this stops a
        search by the clock; a plan it cut short has ``info["time_capped"]`` True (a
        PlanningError: ``details["time_capped"]``) and a warning is logged, since the result
        then depends on the machine's speed.
    """

    turning_radius: float | None = setting(None, PositiveFloat | None)
    transient_margin: float = setting(0.6, NonNegFloat)
    planner: str = setting("lattice", Literal[PLANNERS])
    time_budget: float | None = setting(None, PositiveFloat | None)
    anytime_time: float = setting(0.5, PositiveFloat)
    seed: int | None = 1
    simplify: bool = True
    inflation: float = setting(0.05, NonNegFloat)
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
    speed: float = setting(REFERENCE_SPEED, PositiveFloat)
    cusp_dwell: float = setting(CUSP_DWELL, NonNegFloat)
    straight_pull_ends: bool = True
    pull_start_tolerance: float | None = setting(0.4, NonNegFloat | None)
    rrt_range: float | None = None
    time_cap: float | None = None
    clearance: float | tuple = setting(0.05, NonNegFloat | list[NonNegFloat])
    goal_tolerance: tuple = GOAL_TOLERANCE
    goal_fraction: float = 0.5
    joint_margin: float = angle_setting(5.0, NonNegFloat)
    pull_max_phi: float = angle_setting(15.0, PositiveFloat)
    step_length: float = setting(0.5, PositiveFloat)
    search_weight: float = setting(2.0, Annotated[float, Field(ge=1, allow_inf_nan=False)])
    sample_spacing: float = 0.04
    smooth: bool = setting(True, bool)
    anytime: bool = False
    goal_max_phi: float | None = angle_setting(
        None, Annotated[float, Field(gt=0, lt=90, allow_inf_nan=False)] | None)

    def __post_init__(self):
        name = str(self.planner).lower()
        if name not in PLANNERS:
            raise PlanningInputError(f"planner = {self.planner!r}: allowed are {PLANNERS}")
        object.__setattr__(self, "planner", name)
        positive = ("time_budget", "anytime_time", "planning_resolution", "check_resolution",
                    "radius_growth", "block_radius")
        for key in positive:
            value = getattr(self, key)
            if key == "time_budget" and value is None:
                continue
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
        if self.time_cap is not None and not (
            isinstance(self.time_cap, (int, float)) and math.isfinite(self.time_cap)
            and self.time_cap > 0.0
        ):
            raise PlanningInputError(f"time_cap = {self.time_cap!r} s: must be None or > 0")
        if self.turning_radius is not None and not (
            math.isfinite(self.turning_radius) and self.turning_radius > 0.0
        ):
            raise PlanningInputError(f"turning_radius = {self.turning_radius!r} m: must be > 0")
        if self.check_resolution > 0.01:
            raise PlanningInputError(
                f"check_resolution = {self.check_resolution!r} m: must be <= 0.01"
            )
        clearance = np.atleast_1d(np.asarray(self.clearance, dtype=float))
        if clearance.ndim != 1 or not np.all(np.isfinite(clearance)) or np.any(clearance < 0):
            raise PlanningInputError(
                f"clearance = {self.clearance!r} m: one value or one per body, finite and >= 0")
        object.__setattr__(self, "clearance", float(clearance[0]) if clearance.size == 1
                           else tuple(float(a) for a in clearance))
        tol = tuple(self.goal_tolerance)
        if len(tol) != 2 or not all(math.isfinite(a) and a > 0.0 for a in tol):
            raise PlanningInputError(
                f"goal_tolerance = {self.goal_tolerance!r}: need (position [m], heading [rad]),"
                " both finite and > 0")
        object.__setattr__(self, "goal_tolerance", (float(tol[0]), float(tol[1])))
        for key, low, high in (("joint_margin", 0.0, math.pi), ("pull_max_phi", 0.0, math.pi),
                               ("goal_fraction", 1e-3, 1.0),
                               ("step_length", 1e-3, 100.0), ("search_weight", 1.0, 100.0),
                               ("sample_spacing", 1e-3, 1.0)):
            value = getattr(self, key)
            if not (isinstance(value, (int, float)) and low <= value <= high):
                raise PlanningInputError(f"{key} = {value!r}: allowed {low:g} to {high:g}")
        if self.goal_max_phi is not None and not (
                isinstance(self.goal_max_phi, (int, float)) and 0.0 < self.goal_max_phi < math.pi):
            raise PlanningInputError(
                f"goal_max_phi = {self.goal_max_phi!r} rad: None or in (0, pi)")
        if self.seed is not None and int(self.seed) < 1:
            raise PlanningInputError(f"seed = {self.seed!r}: must be an integer >= 1 or None")
        if int(self.max_attempts) < 1:
            raise PlanningInputError(f"max_attempts = {self.max_attempts!r}: must be >= 1")
        self.tracker()  # validates controller, speed and cusp_dwell

    def tracker(self) -> TrackerConfig:
        """What the whole-train check simulates: controller, reference speed, cusp dwell and
        the goal tolerance."""
        return TrackerConfig(controller=self.controller, speed=self.speed,
                             cusp_dwell=self.cusp_dwell, goal_tolerance=self.goal_tolerance)

    def margins(self, train: Train) -> np.ndarray:
        """The clearance [m] of every body of ``train`` (n+1,), robot first."""
        values = np.atleast_1d(np.asarray(self.clearance, dtype=float))
        if values.size not in (1, train.n + 1):
            raise PlanningInputError(
                f"clearance has {values.size} values: need one, or n + 1 = {train.n + 1} (robot "
                "and every trailer)")
        return np.broadcast_to(values, (train.n + 1,)).copy()

    def budget_steps(self, n: int = 3) -> int:
        """``lattice``: simulated control steps of ``time_budget``, or of the default budget
        for ``n`` trailers (see :mod:`~pushtrain.planner.budget`)."""
        if self.time_budget is None:
            return default_steps(n)
        return steps_for(self.time_budget)

    def budget_seconds(self) -> float:
        """The budget [s]: ``time_budget``, or the default for this planner."""
        if self.time_budget is not None:
            return float(self.time_budget)
        return DEFAULT_SEARCH_SECONDS if self.planner == "lattice" else OMPL_DEFAULT_SECONDS

    def budget_checks(self) -> int:
        """Motion checks of the budget (see :mod:`~pushtrain.planner.budget`)."""
        return checks_for(self.budget_seconds(), "rrtconnect" if self.planner == "lattice"
                          else self.planner)

    def anytime_checks(self) -> int:
        """Motion checks of ``anytime_time``."""
        return checks_for(self.anytime_time, self.planner)

    def wall_cap(self) -> float:
        """The wall-clock safety cap [s] of a plan() call (``time_cap``, or its default)."""
        if self.time_cap is not None:
            return float(self.time_cap)
        if self.time_budget is None:
            return DEFAULT_WALL_CAP
        return 10.0 * self.budget_seconds() + 10.0

    def extension_for(self, radius: float) -> float:
        """RRTConnect's longest tree extension [m] for turning ``radius`` [m]."""
        if self.rrt_range is not None:
            return float(self.rrt_range)
        return 1.3 * float(radius)

    def radius_for(self, train: Train) -> float:
        """The turning radius [m] used for ``train``."""
        if self.turning_radius is not None:
            return float(self.turning_radius)
        return turning_radius_from_joint_limit(
            train.phi_max, train.max_link(), self.transient_margin
        )
