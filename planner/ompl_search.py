"""OMPL search of the last trailer's path: space, motion validator, solve, simplification.

OMPL's camelCase stays in the planner's modules that import ompl (this one and
:mod:`~pushtrain.planner.reeds_shepp`); results are converted to numpy at once. Poses are planner
states (x, y, yaw = theta + pi), see :mod:`~pushtrain.planner.reeds_shepp`.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass, field, replace

import numpy as np
import shapely
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou
from shapely.geometry import Polygon

from pushtrain.errors import PlanningError
from pushtrain.facility.free_space import World

from .budget import CHECKS_PER_SECOND, Work
from .config import OPTIMIZING_PLANNERS, PlannerConfig
from .reeds_shepp import reeds_shepp_space, sample_curve_into, travel_between_states, wrap_yaw
from .repair import (
    first_pull_start_outside,
    pull_end_rule,
    pull_start_rule,
    repair_pull_ends,
    shorten_by_local_search,
)
from .train import Train

__all__ = ["Attempt", "solve_once", "solve_restarts"]

log = logging.getLogger(__name__)

_REFINE_RATIO = 1.2
_CLOCKED = {"prmstar"}  # OMPL planners that evaluate the termination condition on a second thread

_OMPL_LOCK = threading.RLock()
"""Held while the planner calls OMPL, whose log level (and random seed) are process-wide."""


@contextmanager
def _quiet_ompl():
    """Silence OMPL's log while the planner's own OMPL calls run, then restore the caller's level.

    OMPL prints to stdout/stderr; library code must not. Every OMPL failure the planner can
    meet (invalid start/goal, no or approximate solution) becomes a PlanningError instead.
    Re-entrant; threads take turns (:data:`_OMPL_LOCK`), so no thread restores a level another
    one set.
    """
    with _OMPL_LOCK:
        level = ou.getLogLevel()
        ou.setLogLevel(ou.LOG_NONE)
        try:
            yield
        finally:
            ou.setLogLevel(level)


def _allocate_planner(name: str, si):
    """OMPL planner object for ``name``."""
    factory = {
        "rrtconnect": og.RRTConnect,
        "rrtstar": og.RRTstar,
        "bitstar": og.BITstar,
        "prmstar": og.PRMstar,
    }[name]
    return factory(si)


def _set_seed(seed: int) -> None:
    """Seed OMPL's generator. OMPL logs an error when re-seeding after the first draw but does
    re-seed (checked by the tests); that message is silenced here."""
    with _quiet_ompl():
        ou.RNG.setSeed(int(seed))


def _state(space, pose):
    """A state of ``space`` at the planner state ``pose`` (x, y, yaw), yaw wrapped."""
    state = space.allocState()
    state.setX(float(pose[0]))
    state.setY(float(pose[1]))
    state.setYaw(wrap_yaw(pose[2]))
    return state


class _TrailerMotionValidator(ob.MotionValidator):
    """Motion check along OMPL's Reeds-Shepp curve at ``step`` metres: every sampled state
    valid; unless ``allow_pull_arcs``, no heading change while travelling backward; and, with
    ``pull_end_valid``, a free straight train at the end of every backward (pulling) run of the
    curve, located to 1e-6 of the curve by bisection (see :attr:`PlannerConfig.straight_pull_ends`).
    Every check counts one unit of ``work``.
    """

    def __init__(self, si, space, valid_many, step: float, allow_pull_arcs: bool,
                 pull_end_valid=None, pull_start_valid=None, work: Work | None = None):
        super().__init__(si)
        self.work = Work() if work is None else work
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

    def _pull_ends_inside(self, s1, s2, backward: np.ndarray, m: int, length: float):
        """Check the straight train at every end of a backward run inside the curve sampled at
        the fractions k/m (``backward[k - 1]``: sample k-1 -> k). Returns (ok, whether the
        curve ends travelling backward)."""
        # a backward run ending between samples k - 1 and k + 1 (k = 1..m-1)
        for k in np.flatnonzero(backward[:-1] & ~backward[1:]) + 1:
            if not self._pull_end_ok(s1, s2, (k - 1) / m, (k + 1) / m, length):
                return False, False
        # the sign of a whole interval misses a cusp close to either end of the curve:
        # compare with the exact direction there
        if self._backward_at(s1, s2, 0.0, length) and not backward[0]:
            if not self._pull_end_ok(s1, s2, 0.0, 1.0 / m, length):
                return False, False
        end_backward = self._backward_at(s1, s2, max(0.0, 1.0 - 1e-6 / length), length)
        if backward[-1] and not end_backward:
            if not self._pull_end_ok(s1, s2, (m - 1) / m, 1.0, length):
                return False, end_backward
        return True, end_backward

    def _leading_pull_ok(self, s1, pts: np.ndarray, backward: np.ndarray, m: int) -> bool:
        """The pull-start rule for the curve's leading pull (samples 0..end of ``pts``)."""
        forward = np.flatnonzero(~backward)
        end = int(forward[0]) if forward.size else m
        return bool(self._pull_start_valid(s1, pts[: end + 1]))

    def checkMotion(self, s1, s2):  # noqa: N802 (OMPL API)
        self.work.used += 1
        length = self._space.distance(s1, s2)
        if length <= 0.0:
            return bool(self._valid_many(np.array([[s2.getX(), s2.getY(), s2.getYaw()]])))
        m = max(1, int(math.ceil(length / self._step)))
        rows = [(s1.getX(), s1.getY(), s1.getYaw())]
        sample_curve_into(rows, self._space, s1, s2, m, self._tmp)
        pts = np.array(rows)
        # every sample's footprint at once (vectorized shapely); s1 is valid already
        if not self._valid_many(pts[1:]):
            return False
        # travel direction between consecutive samples: backward[k - 1] is sample k-1 -> k
        backward, dyaw, _ = travel_between_states(pts)
        if not self._allow and np.any(backward & (np.abs(dyaw) > 1e-9)):
            return False
        end_backward = False
        if self._pull_end_valid is not None:
            ok, end_backward = self._pull_ends_inside(s1, s2, backward, m, length)
            if not ok:
                return False
        if self._pull_start_valid is not None and backward[0]:
            if not self._leading_pull_ok(s1, pts, backward, m):
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
class Attempt:
    """State of one planning attempt (what the replanning loop changes)."""

    radius: float
    inflation: float
    blocks: list = field(default_factory=list)
    pull_start_tolerance: float | None = None


@dataclass
class _Search:
    """One OMPL problem, set up: ``ss`` (SimpleSetup), ``si``, ``space``, ``validator`` and the
    ``start`` and ``goal`` states."""

    ss: object
    si: object
    space: object
    validator: _TrailerMotionValidator
    start: object
    goal: object


def _footprint_checks(world: World, train: Train, clearance: float):
    """State validity of the last trailer (its footprint inside ``world`` eroded by
    ``clearance`` [m]): one OMPL state, and every row (x, y, yaw) of an array at once."""
    last = train.last
    region = world.eroded(clearance)
    contains = region.contains
    corners_of = last.corner_points

    def is_valid(state) -> bool:
        return bool(contains(Polygon(corners_of(state.getX(), state.getY(),
                                                state.getYaw() + math.pi))))

    def valid_many(pts: np.ndarray) -> bool:
        """Every (x, y, yaw) row's footprint inside the region."""
        polys = shapely.polygons(last.corners(pts[:, 0], pts[:, 1], pts[:, 2] + math.pi))
        return bool(shapely.contains(region, polys).all())

    return is_valid, valid_many


def _set_up(world: World, train: Train, start_yaw, goal_yaw, config: PlannerConfig,
            attempt: Attempt, seed: int | None, start_headings, work: Work) -> _Search:
    """Seed OMPL and set up the problem: space, validity, motion validator with the pull
    rules (counting its checks in ``work``), start and goal, planner."""
    planning_world = world.with_obstacles(attempt.blocks) if attempt.blocks else world
    is_valid, valid_many = _footprint_checks(planning_world, train,
                                             attempt.inflation + config.offtrack_allowance)
    if seed is not None:
        _set_seed(seed)
    space = reeds_shepp_space(attempt.radius, world.bounds)
    ss = og.SimpleSetup(space)
    ss.setStateValidityChecker(is_valid)
    si = ss.getSpaceInformation()
    pull_end_valid = (pull_end_rule(train, planning_world, attempt.inflation)
                      if config.straight_pull_ends else None)
    pull_start_valid = (None if attempt.pull_start_tolerance is None else
                        pull_start_rule(train, attempt.pull_start_tolerance, start_yaw,
                                        start_headings))
    validator = _TrailerMotionValidator(si, space, valid_many, config.planning_resolution,
                                        config.allow_pull_arcs, pull_end_valid, pull_start_valid,
                                        work)
    si.setMotionValidator(validator)
    validator.goal = (float(goal_yaw[0]), float(goal_yaw[1]))
    start, goal = _state(space, start_yaw), _state(space, goal_yaw)
    ss.setStartAndGoalStates(start, goal)
    if config.planner in OPTIMIZING_PLANNERS:
        ss.setOptimizationObjective(ob.PathLengthOptimizationObjective(si))
    planner = _allocate_planner(config.planner, si)
    if config.planner == "rrtconnect":
        planner.setRange(config.extension_for(attempt.radius))
    ss.setPlanner(planner)
    ss.setup()
    return _Search(ss, si, space, validator, start, goal)


def _termination(config: PlannerConfig, work: Work, limit: int):
    """OMPL's termination condition of a solve: ``work`` reaches ``limit`` motion checks, or
    the wall-clock safety cap passes.

    PRM* evaluates the condition on a second thread too, where a condition written in Python
    deadlocks (that thread waits for the GIL, which the planning thread holds while it joins
    it): it stops after ``(limit - work.used) / CHECKS_PER_SECOND["prmstar"]`` seconds, or at
    the cap, by OMPL's own clock.
    """
    if config.planner not in _CLOCKED:
        return ob.PlannerTerminationCondition(lambda: work.done(limit))
    seconds = (limit - work.used) / CHECKS_PER_SECOND[config.planner]
    to_cap = max(work.deadline - time.perf_counter(), 0.0)
    if to_cap < seconds:
        work.capped = True
        log.warning("%s stops at the wall-clock safety cap in %.3g s", config.planner, to_cap)
    return ob.timedPlannerTerminationCondition(min(seconds, to_cap))


def _exact_solution(search: _Search, goal_yaw, config: PlannerConfig, info: dict):
    """The solution path of the solve, or PlanningError (approximate_only, unreachable)."""
    ss = search.ss
    if ss.haveExactSolutionPath():
        return ss.getSolutionPath()
    if ss.haveSolutionPath():
        path = ss.getSolutionPath()
        reached = path.getState(path.getStateCount() - 1)
        gap = float(search.space.distance(reached, search.goal))
        raise PlanningError(
            "approximate_only",
            f"{config.planner} found only an approximate solution within {_budget_text(info)}: "
            f"it ends at ({reached.getX():.3f}, {reached.getY():.3f}), {gap:.3f} m (Reeds-Shepp) "
            f"from the goal ({goal_yaw[0]:.3f}, {goal_yaw[1]:.3f})",
            where=(reached.getX(), reached.getY()), details={"gap": gap, **info},
        )
    raise PlanningError(
        "unreachable",
        f"{config.planner} found no path to the goal ({goal_yaw[0]:.3f}, {goal_yaw[1]:.3f}) "
        f"within {_budget_text(info)} (status {info['status']})",
        where=tuple(goal_yaw[:2]), details=info,
    )


def _budget_text(info: dict) -> str:
    """The budget a solve had, for messages."""
    text = f"{info['budget_checks']} motion checks"
    return text + " (stopped by the wall-clock safety cap)" if info.get("time_capped") else text


def _path_through(si, states: list):
    """OMPL path through ``states``."""
    out = og.PathGeometric(si, states[0])
    for st in states[1:]:
        out.append(st)
    return out


def _shorten(search: _Search, path, config: PlannerConfig, info: dict, refine_limit: int | None,
             refine_below: float, seed: int | None):
    """Simplification (OMPL's reduceVertices, then the greedy shortcut) and, with a
    ``refine_limit`` (motion checks of the search's work) and a path shorter than
    ``refine_below`` [m], the local search."""
    si = search.si
    if config.simplify:
        t1 = time.perf_counter()
        # OMPL's reduceVertices, then the greedy shortcut; OMPL's simplifyMax (to its fixed
        # point) takes 40-100 ms on the bay, 5-10 times the solve, for 2-3 % shorter paths
        og.PathSimplifier(si).reduceVertices(path)
        path = _greedy_shortcut(si, path)
        info["simplify_time"] = time.perf_counter() - t1
    if refine_limit is not None and path.length() < refine_below:
        t1 = time.perf_counter()
        states = shorten_by_local_search(si, search.space, search.validator,
                                         list(path.getStates()), search.validator.work,
                                         refine_limit, np.random.default_rng(seed))
        path = _greedy_shortcut(si, _path_through(si, states))
        info["refine_time"] = time.perf_counter() - t1
    return path


def _apply_pull_rules(search: _Search, path, train: Train, config: PlannerConfig,
                      attempt: Attempt, seed: int | None, start_headings, info: dict) -> list:
    """The path's states after repairing its pull ends; PlanningError (pull_end_blocked,
    pull_start_mismatch) where the finished path breaks a pull rule."""
    path_states = list(path.getStates())
    repaired, blocked = repair_pull_ends(search.si, search.space, search.validator, path_states,
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
        bad = first_pull_start_outside(search.space, path_states, train,
                                       attempt.pull_start_tolerance, start_headings)
        if bad is not None:
            raise PlanningError(
                "pull_start_mismatch",
                f"{config.planner}'s path starts a pull at ({bad[0]:.3f}, {bad[1]:.3f}) that "
                f"needs a chain {bad[2]:.3f} m from the one it starts from (allowed "
                f"{attempt.pull_start_tolerance:.3g} m)",
                where=bad[:2], details=info,
            )
    return path_states


def solve_once(world: World, train: Train, start_yaw, goal_yaw, config: PlannerConfig,
               attempt: Attempt, checks: int, seed: int | None, start_headings=None,
               refine_checks: int = 0, refine_below: float = math.inf,
               work: Work | None = None):
    """One OMPL solve of the last trailer. Returns (states (M,3), info) or raises PlanningError.

    The solve stops after ``checks`` motion checks (counted in ``work``, which also holds the
    wall-clock safety cap; None: a fresh count without a cap). ``refine_checks`` > 0 shortens
    the simplified path further by a local search on its states
    (:func:`~pushtrain.planner.repair.shorten_by_local_search`) until it stops gaining or the work
    since the call's start reaches ``refine_checks``, if the simplified path is shorter than
    ``refine_below`` [m]."""
    work = Work() if work is None else work
    used0 = work.used
    limit = used0 + max(1, int(checks))
    with _quiet_ompl():
        search = _set_up(world, train, start_yaw, goal_yaw, config, attempt, seed, start_headings,
                         work)
        si, space, start, goal = search.si, search.space, search.start, search.goal
        t0 = time.perf_counter()
        if si.isValid(start) and si.isValid(goal) and si.checkMotion(start, goal):
            # The shortest Reeds-Shepp curve itself is free: it is the optimal path.
            info = {"status": "direct", "solve_time": time.perf_counter() - t0,
                    "planner_time": time.perf_counter() - t0, "checks": work.used - used0}
            states = np.array([[p.getX(), p.getY(), p.getYaw()] for p in (start, goal)])
            info["raw_length"] = info["length_ompl"] = float(space.distance(start, goal))
            return states, info
        status = search.ss.solve(_termination(config, work, limit))
        info = {"status": str(status), "solve_time": time.perf_counter() - t0,
                "planner_time": search.ss.getLastPlanComputationTime(),
                "budget_checks": limit - used0, "time_capped": work.capped}
        path = _exact_solution(search, goal_yaw, config, info)
        info["raw_length"] = float(path.length())
        refine_limit = used0 + int(refine_checks) if refine_checks > 0 else None
        path = _shorten(search, path, config, info, refine_limit, refine_below, seed)
        path_states = _apply_pull_rules(search, path, train, config, attempt, seed, start_headings,
                                        info)
        states = np.array([[s.getX(), s.getY(), s.getYaw()] for s in path_states])
        info["length_ompl"] = float(sum(
            space.distance(a, b) for a, b in zip(path_states[:-1], path_states[1:], strict=True)
        ))
        info["checks"] = work.used - used0
        info["time_capped"] = work.capped
        return states, info


def solve_restarts(world: World, train: Train, start_yaw, goal_yaw, config: PlannerConfig,
                   attempt: Attempt, checks: int, seed: int | None, start_headings=None,
                   work: Work | None = None):
    """Anytime planning by restarts: RRTConnect, simplification and a local search on the
    path's states (:func:`~pushtrain.planner.repair.shorten_by_local_search`, until it stops
    gaining) again and again, each with its own seed (derived from ``seed``), until the restarts
    have done ``checks`` motion checks (counted in ``work``); the shortest path wins. A restart
    whose shortest Reeds-Shepp curve is free ends the search: no path is shorter.

    Not asymptotically optimal like RRT* or BIT*, but each restart is a complete, locally
    shortest path within about 100 motion checks (0.1 s), which in corridors beats the
    optimizing planners at short budgets (``benchmarks/bench_planner.py``). At least one
    restart runs to its end. Returns (states, info) of the shortest; raises the last
    PlanningError if none succeeded.
    """
    work = Work() if work is None else work
    t0, used0 = time.perf_counter(), work.used
    limit = used0 + max(1, int(checks))
    single = replace(config, planner="rrtconnect")
    rng = np.random.default_rng(seed)
    best, runs, first_time, last_error = None, 0, None, None
    while not (runs and work.done(limit)):
        # the first restart is RRTConnect with ``seed`` itself, so the result is never longer
        # than the default planner's path for the same seed
        run_seed = seed if (seed is None or runs == 0) else int(rng.integers(1, 2**31 - 1))
        remaining = max(limit - work.used, 1)
        runs += 1
        try:
            # the local search gains 5-15 %: a restart far longer than the best so far is
            # not worth it
            below = math.inf if best is None else _REFINE_RATIO * best[1]["length_ompl"]
            states, info = solve_once(world, train, start_yaw, goal_yaw, single, attempt,
                                      remaining, run_seed, start_headings,
                                      refine_checks=remaining, refine_below=below, work=work)
        except PlanningError as exc:
            last_error = exc
            continue
        if first_time is None:
            first_time = time.perf_counter() - t0
        if best is None or info["length_ompl"] < best[1]["length_ompl"]:
            best = (states, info)
        if info["status"] == "direct":
            break
    if best is None:
        raise last_error
    states, info = best
    info = {**info, "restarts": runs, "planner_time": first_time, "checks": work.used - used0,
            "solve_time": time.perf_counter() - t0, "time_capped": work.capped}
    return states, info


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
