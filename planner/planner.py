"""The whole-train planning loop: :func:`plan` and its replanning after failed train checks.

``plan`` plans the last trailer's line/arc path with OMPL (:mod:`~pushtrain.planner.ompl_search`),
computes its segments (:mod:`~pushtrain.planner.reeds_shepp`) and checks the whole train on it by
simulating the co-simulation's controller in closed loop with the chain
(:mod:`~pushtrain.planner.train_check`); a failure changes the next attempt (larger radius, or
a blocked region and more inflation, see :func:`_next_attempt`) until a plan passes,
``max_attempts`` or ``time_budget`` run out. Budgets count work (motion checks, see
:mod:`~pushtrain.planner.budget`), so a seed gives the same plan on any machine and under any
load; the wall clock only stops planning at the safety cap ``time_cap``. The planner's
settings and turning-radius rule are in :mod:`~pushtrain.planner.config`, its pull rules in
:mod:`~pushtrain.planner.repair`.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from shapely.geometry import Point
from shapely.geometry import box as _box

from pushtrain.core.kinematics import body_positions
from pushtrain.core.segment import PULL, Segment
from pushtrain.errors import PlanningError, PlanningInputError
from pushtrain.facility.free_space import World

from .budget import STEPS_PER_CHECK, Work
from .config import ANYTIME_PLANNERS, PlannerConfig, TrackerConfig
from .ompl_search import Attempt, solve_once, solve_restarts
from .path import PlannedPath, reference_times
from .reeds_shepp import chain_to_planner_state, segments_from_states
from .train import Train
from .train_check import check_train
from .whole_train import check_lattice_ends, plan_lattice

__all__ = ["check_mission", "plan"]

log = logging.getLogger(__name__)

_PULL_RULES = ("pull_end_blocked", "pull_start_mismatch")
"""PlanningError reasons of the planner's own pull rules: the next attempt takes the next seed."""


def _checked_poses(start, goal, train: Train, start_headings):
    """``start``, ``goal`` (3,) and ``start_headings`` (n+1,) or None as float arrays;
    PlanningInputError if malformed."""
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
    return start, goal, start_headings


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

    x, y = body_positions(float(start[0]), float(start[1]), theta0, train.geometry, from_last=True)
    for i, body in enumerate(train.bodies):
        poly = body.polygons(x[i], y[i], theta0[i])
        if not region.contains(poly):
            name = "robot" if i == 0 else f"trailer {i}"
            raise PlanningError(
                "start_in_collision",
                f"at the start the {name} (body {i}) at ({x[i]:.3f}, {y[i]:.3f}), heading "
                f"{math.degrees(theta0[i]):.1f} deg, is not inside the free space with "
                f"{inflation} m clearance",
                where=(x[i], y[i], theta0[i]), details={"body": i},
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
                f"the goal ({goal[0]:.3f}, {goal[1]:.3f}) lies in a part of the map the last "
                f"trailer cannot reach from the start ({start[0]:.3f}, {start[1]:.3f}): every "
                f"connection is narrower than {2 * half:.3f} m (trailer width + 2 x clearance)",
                where=tuple(goal[:2]), details={"start_piece": ka, "goal_piece": kb},
            )


def check_mission(world: World, start: Sequence[float], goal: Sequence[float], train: Train,
                  config: PlannerConfig | None = None,
                  start_headings: Sequence[float] | None = None) -> None:
    """What :func:`plan` refuses before it searches, without searching (a scenario's check):
    malformed poses (PlanningInputError), an empty map, a start or goal that misses its
    clearance, and, for the lattice planner, a goal no way as wide as the last trailer reaches
    ("impossible here"). Raises that PlanningError, else returns. Same arguments as
    :func:`plan`."""
    config = config or PlannerConfig()
    start, goal, start_headings = _checked_poses(start, goal, train, start_headings)
    if config.planner == "lattice":
        check_lattice_ends(world, train, start, goal, start_headings, config)
    else:
        _check_endpoints(world, train, start, goal, start_headings, config.inflation)


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
    start, goal, start_headings = _checked_poses(start, goal, train, start_headings)
    if config.planner == "lattice":
        return plan_lattice(world, train, start, goal, start_headings, config)
    _check_endpoints(world, train, start, goal, start_headings, config.inflation)

    tracker = config.tracker()
    tracker.controller_for(train.geometry)  # a controller for another n fails here, not later
    initial = Attempt(config.radius_for(train), config.inflation,
                      pull_start_tolerance=config.pull_start_tolerance)
    attempt = initial
    history = []
    last_error: PlanningError | None = None
    last_result = None
    work = Work(deadline=t_begin + config.wall_cap())
    total = config.budget_checks()
    for k in range(int(config.max_attempts)):
        if work.done(total):
            break
        seed = None if config.seed is None else int(config.seed) + k
        used0 = work.used
        try:
            states, info = _search(world, train, start, goal, config, attempt,
                                   _checks_for_attempt(config, k, total - work.used), seed,
                                   start_headings, work)
        except PlanningError as exc:
            last_error = exc
            history.append({"attempt": k, "radius": attempt.radius, "inflation": attempt.inflation,
                            "blocks": len(attempt.blocks), "error": exc.reason,
                            "checks": work.used - used0})
            if exc.reason in _PULL_RULES:
                continue  # a rule of the planner's own, not of the train check: next seed
            if k == 0 or exc.reason not in ("unreachable", "approximate_only"):
                break
            # a replanning change made the goal unreachable: undo the changes, try a new seed
            attempt = replace(initial)
            continue
        segments = _segments(states, attempt.radius)
        entry = {"attempt": k, "radius": attempt.radius, "inflation": attempt.inflation,
                 "blocks": len(attempt.blocks), "seed": seed, **info}
        result = _train_check(world, train, start, segments, start_headings, config, tracker,
                              work, entry)
        history.append(entry)
        if result is None or result.ok:
            return _planned(start, segments, start_headings, attempt, config, tracker, result,
                            history, t_begin, work)
        last_result = result
        attempt = _next_attempt(attempt, result.failure, train, config, segments)
        attempt.blocks = _clear_of_ends(attempt, train, config, start, goal)
    raise _final_error(last_result, last_error, history, train, config, goal, t_begin, work)


def _train_check(world: World, train: Train, start, segments, start_headings,
                 config: PlannerConfig, tracker: TrackerConfig, work: Work, entry: dict):
    """The whole-train check of a plan (None if ``config.check_train`` is off), charged to
    ``work`` and noted in the attempt's ``entry``."""
    if not config.check_train:
        return None
    result = check_train(world, train, start, segments, start_headings, margin=config.inflation,
                         resolution=config.check_resolution, tracker=tracker)
    work.used += result.simulated_t.size // STEPS_PER_CHECK
    entry["train_ok"] = result.ok
    entry["failure"] = result.failure
    return result


def _checks_for_attempt(config: PlannerConfig, k: int, remaining: int) -> int:
    """Motion checks of attempt ``k`` with ``remaining`` checks of the budget left."""
    if config.planner in ANYTIME_PLANNERS:
        return min(config.anytime_checks(), remaining)
    # a replan may find nothing (e.g. a block closed the corridor): it gets half of what is
    # left, so that another try remains
    return remaining if k == 0 else max(1, remaining // 2)


def _search(world: World, train: Train, start, goal, config: PlannerConfig,
            attempt: Attempt, checks: int, seed: int | None, start_headings, work: Work):
    """The last trailer's path (planner states (M, 3), info) for one attempt."""
    solve = solve_restarts if config.planner == "restarts" else solve_once
    return solve(world, train, chain_to_planner_state(start), chain_to_planner_state(goal),
                 config, attempt, checks, seed, start_headings, work=work)


def _segments(states: np.ndarray, radius: float) -> list[Segment]:
    """Line/arc segments through ``states``, verified against OMPL's curve."""
    segments, deviation = segments_from_states(states, radius)
    if deviation > 1e-6:
        raise RuntimeError(
            f"the Reeds-Shepp segments computed deviate {deviation:.3g} m from OMPL's curve"
        )
    return segments


def _planned(start, segments, start_headings, attempt: Attempt, config: PlannerConfig,
             tracker: TrackerConfig, result, history: list, t_begin: float,
             work: Work) -> PlannedPath:
    """The PlannedPath of a plan that passed (``result``: its train check, or None)."""
    info_all = {
        "planner": config.planner, "seed": config.seed, "attempts": history,
        "radius": attempt.radius, "inflation": attempt.inflation,
        "time": time.perf_counter() - t_begin,
        "checks": work.used, "budget_checks": config.budget_checks(),
        "time_capped": work.capped,
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
    path = PlannedPath(start, tuple(segments), attempt.radius, start_headings,
                       config.check_resolution, info_all)
    if result is not None:
        path.headings = _resample_headings(result, path, tracker)
    log.info("planned %.2f m, %d segments, %d cusps in %.3f s (%d attempts)",
             path.length, len(segments), path.n_cusps, info_all["time"], len(history))
    return path


def _clear_of_ends(attempt: Attempt, train: Train, config: PlannerConfig, start, goal) -> list:
    """The attempt's blocks without those that touch the last trailer's own start or goal
    footprint (never blocked)."""
    keep_clear = [train.last.polygons(*pose).buffer(attempt.inflation + config.offtrack_allowance)
                  for pose in (start, goal)]
    return [b for b in attempt.blocks if not any(b.intersects(k) for k in keep_clear)]


def _final_error(last_result, last_error: PlanningError | None, history: list, train: Train,
                 config: PlannerConfig, goal, t_begin: float, work: Work) -> PlanningError:
    """The PlanningError of a plan() that found no plan passing the train check
    (``details["time_capped"]``: whether the wall-clock safety cap stopped a search)."""
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
        error = PlanningError(
            "train_check_failed",
            f"after {len(history)} attempts ({time.perf_counter() - t_begin:.2f} s) the whole "
            f"train still fails: the {name} {what} at t = {f['t']:.2f} s, s = {f['s']:.2f} m of "
            "the last plan",
            where=(f["x"], f["y"]), details={"failure": f, "attempts": history},
        )
    elif last_error is not None:
        error = last_error
        error.details.setdefault("attempts", history)
    else:
        what = (f"before the wall-clock safety cap of {config.wall_cap():.3g} s" if work.capped
                else f"within the budget of {config.budget_checks()} motion checks (time_budget "
                f"{config.budget_seconds():g} s)")
        error = PlanningError("unreachable", f"no plan {what}", where=tuple(goal[:2]),
                              details={"attempts": history})
    error.details["time_capped"] = work.capped
    return error


def _resample_headings(result, path: PlannedPath, tracker: TrackerConfig) -> np.ndarray:
    """The closed-loop simulation's headings at the times the reference passes the path's dense
    samples (at a cusp: when it arrives there). They belong to the simulated train, whose last
    trailer is near, not exactly at, :attr:`PlannedPath.poses`."""
    t, _ = reference_times(path.segments, tracker.speed, tracker.cusp_dwell, path.s)
    return result.headings_at(t)


def _next_attempt(attempt: Attempt, failure: dict, train: Train, config: PlannerConfig,
                  segments: Sequence[Segment] = ()) -> Attempt:
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
