"""The whole-train planner (``planner = "lattice"``, the default): checks, search, verification.

:func:`plan_lattice` is what :func:`~pushtrain.planner.planner.plan` runs by default:

1. **Ends.** The map must have room for the last trailer; the train at the start and the last
   trailer at the goal must keep their clearances (``PlannerConfig.clearance``, per body),
   tested with the distance field and, where that fails, measured exactly (shapely) for the
   message: a goal that leaves the last trailer 3 cm from a wall when the scenario asks 5 cm
   says so with those numbers.
2. **Search.** :class:`~pushtrain.planner.lattice.Search` over closed-loop train states,
   within ``budget_steps`` simulated control steps (``time_budget`` at
   :data:`~pushtrain.planner.budget.STEPS_PER_SECOND`); the wall clock only as a safety net
   far above it (``PlannerConfig.wall_cap``).
3. **Verification.** A path the search found is simulated again in one go from the start with
   exactly the co-simulation's reference (one :class:`~pushtrain.core.reference.Reference`,
   cusp dwells, pull guides over whole pulling runs) and the search's checks.
4. **Smoothing.** :mod:`~pushtrain.planner.smooth` merges equal pieces and replaces
   stretches by corner and Reeds-Shepp shortcuts where the closed loop allows (fewer turns,
   shorter), each candidate simulated as from the start (continued, bit for bit, from the run
   of the path it parts from: ``_simulate``'s ``base``).
5. **Exact test.** The final path's run is checked with
   :func:`~pushtrain.planner.train_check.check_train`: every body's exact rectangle (shapely)
   against the free space shrunk by its clearance, the joint limit, self-collision and the goal
   tolerance, and the clearances measured. If the smoothed path fails it, the path as found
   is tested; a path that fails is dropped and the search goes on.
6. **Anytime** (``PlannerConfig.anytime``): the search goes on after the first path until its
   budget is spent, and the cheapest verified path (length, turning, cusps) is kept.

A search that ends without a plan raises :class:`~pushtrain.errors.PlanningError`
(:mod:`~pushtrain.planner.failures`) whose message
says what blocked the motions it tried (walls and which body, the joint limit, the pull rule,
self-collision, the budget) with numbers, and whose ``details`` carry the explored tree, the
best partial plan and the collision points for ``planning_failure.png``.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, replace

import numpy as np
import shapely
from shapely.geometry import Point

from pushtrain.core.engine import join_runs
from pushtrain.core.kinematics import body_positions
from pushtrain.core.segment import PULL
from pushtrain.errors import PlanningError
from pushtrain.facility.free_space import World

from .config import TrackerConfig
from .failures import no_plan, unreachable, widest_way
from .footprint import body_name, body_samples
from .heuristic import Heuristic
from .lattice import Search
from .lattice_settings import LatticeSettings
from .passage import needed_half_width, passable, swept_band
from .path import PlannedPath, reference_times
from .propagate import Cursor, Propagator
from .route import loop_route, passes_back, starts_against
from .smooth import merge, path_cost, shortcut
from .train import Train
from .train_check import check_train
from .turnable import turnable_route

__all__ = ["check_lattice_ends", "plan_lattice"]

log = logging.getLogger(__name__)

FINE_SPACINGS = (0.01, 0.004)
"""Sample spacings [m] of the bodies' outlines tried, in turn, when the start passes the exact
clearance test but not the sampled one (conservative by half the spacing): a start 0.06 m off a
wall with a 0.05 m clearance moves with 1 cm samples."""

HEURISTIC_NODES_PER_SECOND = 1.0e6
"""Nodes a second assumed of the heuristic's grid Dijkstra when sizing it to the time budget
(conservative: 3.5 million on a laptop core)."""


def plan_lattice(world: World, train: Train, start, goal, start_headings, config) -> PlannedPath:
    """Plan with the closed-loop lattice search (see the module docstring).

    ``start``, ``goal`` (3,) and ``start_headings`` (n+1,) are checked arrays (chain
    convention); ``config`` a :class:`~pushtrain.planner.config.PlannerConfig`.

    Budgets count work (simulated control steps), so the plan is a function of the scenario
    alone; the wall clock only stops the search at the safety cap
    (:meth:`~pushtrain.planner.config.PlannerConfig.wall_cap`: 50 s at the default budget),
    and a result cut short by it says so.
    """
    world.distance_field()  # (prepared before the clock starts; cached)
    t_begin = time.perf_counter()
    deadline = t_begin + config.wall_cap()
    loop = _checked_loop(world, train, start, goal, start_headings, config)
    field, margins, tracker, prop = loop.field, loop.margins, loop.tracker, loop.prop
    headings, state0, phi_limit = loop.headings, loop.state0, loop.phi_limit
    radius = config.radius_for(train)
    last = train.last
    passage = needed_half_width(train, margins[-1])
    # the grid's Dijkstra run (about 3.5 million nodes a second on a laptop core) is not
    # interruptible: it may take at most a quarter of the budget at a million nodes a second
    # the car heuristic pulls only after a straight push that straightens the chain (about
    # 0.6 of the train's length: the three-point turns' last push before their cusp). Its
    # other rule, pulls only where the straight train fits (CarGrid's train_length), is left
    # out: it sent the island loop with 4 and 5 trailers round the island (planned in 7 s
    # instead of not at all) but lost the T junction's K-turn with 3 to 5 trailers
    heuristic = Heuristic(field, goal, radius, passage, build_car=False,
                          car={"straighten": max(1.0, 0.6 * train.hitch_length)},
                          max_nodes=int(HEURISTIC_NODES_PER_SECOND * 0.25
                                        * config.budget_seconds()))
    cursor0 = Cursor(float(start[0]), float(start[1]), float(start[2]), 0.0, 0)
    # the route of the last trailer (the body that goes everywhere the train goes: it leads
    # into docks and bays), kept to the middle of corridors; made when the search first needs
    # it (a goal the start connects to straight away needs none)
    half_width = 0.5 * last.width + float(margins[-1])
    if heuristic(cursor0.pose) == math.inf:
        raise unreachable(field, train, start, goal, passage, impossible=False,
                           grid=heuristic.resolution)

    def route_of():
        route = turnable_route(field, train, start, goal, half_width, config, margins)
        if route is not None and starts_against(route, start):
            # the goal is behind the train: a way round (an island, a hall) pushing only and
            # back past the start is the driver's route, and leads the search (see
            # Heuristic.build_loop)
            band = swept_band(train, radius, margins)
            loop = heuristic.build_loop(start, (band.r_in + passage, band.r_out - passage))
            loop = None if loop is None else loop_route(loop, field, half_width)
            if loop is not None and passes_back(loop, start):
                route = loop
                log.info("the goal is behind the train: a loop round, %.1f m", route.length)
            else:
                heuristic.loop = None  # another way to a far goal: the driver's route leads
        if route is not None:
            log.info("route %.1f m", route.length)
        return route

    # with a straight train asked for at the goal, the final straight approach is as long as
    # the train (the followers line up behind the last trailer on it)
    approach = 1.5 if config.goal_max_phi is None else max(1.5, train.hitch_length + 0.5)
    settings = LatticeSettings(
        radius=radius, step_length=config.step_length, weight=config.search_weight,
        pull_phi=config.pull_max_phi, budget_steps=config.budget_steps(train.n), deadline=deadline,
        approach=approach)
    search = Search(train, prop, heuristic, state0, cursor0, goal, settings, route=route_of)
    rejected, best, found = 0, None, 0
    while True:
        solution = search.next_solution()
        if solution is None:
            break
        run = solution.rollout  # the connection's run is the whole path's if it left the start
        if not run.from_start:
            run = _simulate(prop, start, headings, solution.segments, goal, deadline)
        if not run.ok and run.failure["kind"] in ("deadline", "budget"):
            search.stats.cut = run.failure["kind"]
            break
        if run.ok:
            segments, run, smooth_info = _smoothed(prop, start, headings, solution.segments,
                                                   run, goal, config, train, deadline,
                                                   clear=search.reference_clear)
            if not _exact_fits(run, train, deadline):
                search.stats.cut = "deadline"
                break
            checked = _exact(world, train, start, headings, segments, run, margins, tracker)
            if not checked.ok and segments != solution.segments:
                # the smoothed path failed the exact test: the path as found
                log.info("the smoothed path failed the exact test: %s", checked.failure)
                segments = merge(solution.segments)
                run = _simulate(prop, start, headings, segments, goal, None)
                if not _exact_fits(run, train, deadline):
                    search.stats.cut = "deadline"
                    break
                checked = _exact(world, train, start, headings, segments, run, margins,
                                 tracker)
                smooth_info["shortcuts"] = 0
        else:
            checked = _Refused(run.failure)
        if not checked.ok:
            rejected += 1
            log.info("verification dropped a path: %s", checked.failure)
            search.stats.record({**checked.failure,
                                 "kind": "verification_" + checked.failure["kind"]})
            continue
        found += 1
        cost = path_cost(segments)
        if best is None or cost < best[0] - 1e-9:
            best = (cost, segments, checked, smooth_info)
        if not config.anytime:
            break
    if best is None:
        raise no_plan(search, train, goal, config, margins, phi_limit, t_begin,
                       widest_way(field, train, start, goal, config, margins, search.route))
    _, segments, checked, smooth_info = best
    smooth_info["solutions"] = found
    return _planned(start, headings, segments, radius, config, tracker, checked, search,
                    t_begin, rejected, smooth_info)


@dataclass
class _Loop:
    """The closed loop the search runs from the start (see :func:`_checked_loop`)."""

    field: object
    margins: np.ndarray
    tracker: TrackerConfig
    prop: Propagator
    headings: np.ndarray
    state0: object
    phi_limit: float


def _checked_loop(world: World, train: Train, start, goal, start_headings, config) -> _Loop:
    """The checks made before any search, and the closed loop the search runs.

    Raises PlanningError where the map has no free space, the train at the start or the last
    trailer at the goal misses its clearance (measured exactly), or no way as wide as the last
    trailer's disc joins start and goal ("impossible here", one labelling of the distance
    field). A start that keeps its clearance but not the sampled test's slack gets finer
    outline samples (:data:`FINE_SPACINGS`)."""
    field = world.distance_field()
    margins = config.margins(train)
    # the prediction must end within a fraction of the co-simulation's goal tolerance: the rest
    # is left to the difference between the kinematic prediction and the FMU
    tol = config.goal_tolerance
    tracker = replace(config.tracker(), goal_tolerance=(config.goal_fraction * tol[0],
                                                        config.goal_fraction * tol[1]))
    controller = tracker.controller_for(train.geometry)
    samples = body_samples(train, margins, spacing=config.sample_spacing)
    phi_limit = train.phi_max - config.joint_margin
    prop = Propagator(train, controller, tracker, field, samples, phi_limit,
                      goal_phi=config.goal_max_phi)
    headings = (np.full(train.n + 1, float(start[2])) if start_headings is None
                else np.asarray(start_headings, dtype=float))
    state0 = prop.initial_state(start, headings)
    _check_ends(world, train, start, goal, state0, prop, margins)
    for spacing in FINE_SPACINGS:
        failure, _ = prop.check(np.array([state0.z]))
        if failure is None or failure["kind"] != "collision" or spacing >= config.sample_spacing:
            break
        # the exact test passed the start (_check_ends): what refuses it is the sampled test's
        # slack (half the sample spacing), and no motion could leave it. Finer samples let a
        # train that starts a few centimetres off a wall move off it.
        log.info("the start keeps its clearance but not the sampled test's slack: samples "
                 "every %.3f m", spacing)
        samples = body_samples(train, margins, spacing=spacing)
        prop = Propagator(train, controller, tracker, field, samples, phi_limit,
                          goal_phi=config.goal_max_phi)
        state0 = prop.initial_state(start, headings)
    # no way as wide as the last trailer's disc: impossible, said before any search
    passage = needed_half_width(train, margins[-1])
    if not passable(field, start, goal, passage):
        raise unreachable(field, train, start, goal, passage, impossible=True)
    return _Loop(field, margins, tracker, prop, headings, state0, phi_limit)


def check_lattice_ends(world: World, train: Train, start, goal, start_headings, config) -> None:
    """What :func:`plan_lattice` refuses before any search (see :func:`_checked_loop`), without
    searching: raises its PlanningError, else returns."""
    _checked_loop(world, train, start, goal, start_headings, config)


# --------------------------------------------------------------------------- the ends
def _check_ends(world: World, train: Train, start, goal, state0, prop: Propagator, margins):
    """Raise PlanningError if the map is empty, the train at the start or the last trailer at
    the goal misses its clearance (numbers measured exactly where the map has polygons)."""
    if world.free.is_empty or world.free_area <= 1e-12:
        raise PlanningError(
            "no_free_space",
            f"the map has no free space (free area {world.free_area:.3g} m² inside outline bounds "
            f"{tuple(round(b, 3) for b in world.outline.bounds)})", details={"constraint": "map"})
    z = np.array([state0.z])
    failure, _ = prop.check(z)
    if failure is not None and failure["kind"] != "collision":
        what = ("a joint angle beyond the limit" if failure["kind"] == "joint_limit"
                else "bodies folded onto each other")
        raise PlanningError("start_in_collision", f"the start has {what}: {failure}",
                            where=(failure["x"], failure["y"]),
                            details={"body": failure["body"], "constraint": failure["kind"]})
    x, y = body_positions(z[:, 0], z[:, 1], z[:, 2:], train.geometry)
    th = z[0, 2:]
    for i, body in enumerate(train.bodies):
        gap = _exact_gap(world, body.polygons(x[0, i], y[0, i], th[i]))
        if failure is not None and failure["body"] == i or gap < margins[i] - 1e-9:
            if gap >= margins[i] - 1e-9:
                continue  # the sampled test is conservative; the exact one passes
            raise PlanningError(
                "start_in_collision",
                f"at the start the {body_name(i)} (body {i}) at ({x[0, i]:.3f}, {y[0, i]:.3f}), "
                f"heading {math.degrees(th[i]):.1f} deg, {_gap_text(gap, margins[i])}",
                where=(x[0, i], y[0, i], th[i]),
                details={"body": i, "gap": gap, "margin": float(margins[i]),
                         "constraint": "start footprint vs clearance"})
    n = train.n
    gap = _exact_gap(world, train.last.polygons(*goal))
    if gap < margins[n] - 1e-9:
        raise PlanningError(
            "goal_in_collision",
            f"at the goal the last trailer at ({goal[0]:.3f}, {goal[1]:.3f}), heading "
            f"{math.degrees(goal[2]):.1f} deg, {_gap_text(gap, margins[n])}",
            where=tuple(goal), details={"body": n, "gap": gap, "margin": float(margins[n]),
                                        "constraint": "goal footprint vs clearance"})


def _exact_gap(world: World, poly) -> float:
    """Distance [m] from ``poly`` to the walls: positive inside the free space, minus the
    depth of the overlap's farthest point if it leaves it (approximate), -inf if wholly out."""
    poly = shapely.geometry.Polygon(poly) if not hasattr(poly, "geom_type") else poly
    free = world.eroded(0.0)  # this thread's prepared copy
    if free.covers(poly):
        return float(world.wall_distance([poly])[0])
    outside = poly.difference(free)
    if outside.is_empty:
        return 0.0
    depth = max(free.distance(Point(p)) for p in np.asarray(
        shapely.get_coordinates(outside)))
    return -float(depth)


def _gap_text(gap: float, margin: float) -> str:
    if gap >= 0.0:
        return (f"keeps only {gap:.3f} m from the walls; planner.clearance asks {margin:.3f} m "
                "for it")
    return (f"reaches {-gap:.3f} m into a wall (planner.clearance asks {margin:.3f} m of "
            "clearance)")


# --------------------------------------------------------------------------- verification
def _simulate(prop: Propagator, start, headings, segments, goal, deadline: float | None,
              base: tuple | None = None):
    """The whole path simulated from the start with the co-simulation's reference (one
    :class:`~pushtrain.core.reference.Reference`: cusp dwells, pull guides over whole pulling
    runs) and the search's checks; it stops at the first failure or at ``deadline`` (failure
    kind ``"deadline"``).

    ``base`` = (segments, run): a whole run from the start of another path. Up to a little
    before the end of the leading segments both paths share (:func:`_shared_until`), the
    reference, the pull guides and so the closed loop are the same to the bit: those rows are
    taken from it and the loop continues from its state there (the same run as from the
    start, in fewer steps)."""
    state0 = prop.initial_state(start, headings)
    cursor0 = Cursor(float(start[0]), float(start[1]), float(start[2]), 0.0, 0)
    head = None
    if base is not None:
        k = _shared_until(prop, base[0], segments)
        if k >= 1 and base[1].ok and k < base[1].state.k:
            head = base[1].run.head(k)
            state0 = head.end
    run = prop.rollout(state0, cursor0, segments, goal=goal, deadline=deadline)
    if head is not None:
        run = replace(run, run=join_runs([head, run.run]))
    return run


def _shared_until(prop: Propagator, base, segments) -> int:
    """The last instant at which the closed loops along ``base`` and ``segments`` (two paths
    from the same start) are still the same: two instants before the end of the leading
    segments they share, or before the pulling run that ends there (its pull guide depends on
    where the run ends); 0 where they share none."""
    p = 0
    for a, b in zip(base, segments, strict=False):
        if a != b:
            break
        p += 1
    after = {g[p].direction for g in (base, segments) if p < len(g)}
    if p > 0 and base[p - 1].direction == PULL and PULL in after:
        while p > 0 and base[p - 1].direction == PULL:
            p -= 1
    if p == 0:
        return 0
    shared = base[:p]
    times, _ = reference_times(shared, prop.tracker.speed, prop.tracker.cusp_dwell,
                               [sum(g.length for g in shared)])
    return max(0, prop.loop.instant_at(float(times[0])) - 2)


_EXACT_RATE = [2.0e-6]
"""Seconds per simulated state and body of the exact test, the last measured in this process
(at first a conservative guess: about 0.7 us is usual)."""


def _exact_fits(run, train: Train, deadline: float) -> bool:
    """Whether the exact test of ``run`` is expected to end before ``deadline`` (a
    ``time.perf_counter()`` value, the wall-clock safety cap): it cannot be interrupted, so
    one that would end past the cap is not started (the result says the clock cut the search
    short)."""
    estimate = _EXACT_RATE[0] * run.run.states.shape[0] * (train.n + 1)
    if time.perf_counter() + estimate <= deadline:
        return True
    log.info("no time left for the exact test of a path found (about %.3f s)", estimate)
    return False


def _exact(world: World, train: Train, start, headings, segments, run, margins,
           tracker: TrackerConfig):
    """The exact test of a simulated path: every body's rectangle (shapely) inside the free
    space shrunk by its clearance at samples no corner moves more than 1 cm apart, the joint
    limit, self-collision and the goal, with the clearances measured
    (:func:`~pushtrain.planner.train_check.check_train` on the run, no new simulation)."""
    t0 = time.perf_counter()
    checked = check_train(world, train, start, segments, headings, margin=margins,
                          resolution=0.01, tracker=tracker, run=run.run,
                          self_collision=True, field=world.distance_field())
    _EXACT_RATE[0] = (time.perf_counter() - t0) / (run.run.states.shape[0] * (train.n + 1))
    return checked


@dataclass
class _Refused:
    """A path the simulation already failed (no exact test made)."""

    failure: dict
    ok: bool = False


# --------------------------------------------------------------------------- smoothing
def _smoothed(prop, start, headings, segments, run, goal, config, train, deadline,
              clear=None):
    """Merge equal consecutive pieces and try shortcuts (:mod:`.smooth`), each simulated in
    one go from the start with the search's checks. Returns (segments, their run, info)."""
    merged = merge(segments)
    info = {"pieces_found": len(segments), "pieces_merged": len(merged), "shortcuts": 0}
    if not config.smooth:
        return merged, run, info

    # the path whose whole run is at hand: the search's, then each shortcut taken (shortcut
    # takes every candidate verify passes); each candidate's run continues it where they part
    base = [segments, run]

    def verify(candidate):
        result = _simulate(prop, start, headings, candidate, goal, deadline, base=tuple(base))
        if result.ok:
            base[:] = [candidate, result]
        return result

    best, best_run, n_short = shortcut(merged, run, start, goal, config.radius_for(train),
                                       verify, deadline, clear=clear)
    info["shortcuts"] = n_short
    return best, best_run, info


# --------------------------------------------------------------------------- results
def _planned(start, headings, segments, radius, config, tracker, checked, search: Search,
             t_begin, rejected, smooth_info) -> PlannedPath:
    stats = search.stats
    info = {
        "planner": "lattice", "seed": config.seed, "time": time.perf_counter() - t_begin,
        "steps": search.prop.steps, "budget_steps": config.budget_steps(search.train.n),
        "time_capped": stats.cut == "deadline", "expansions": stats.expansions,
        "rollouts": stats.rollouts, "rejected_by_verification": rejected,
        "failures": dict(stats.failures), "radius": radius,
        "steps_by_use": {**stats.steps, "verification": search.prop.steps
                         - sum(stats.steps.values())},
        "car_heuristic_at": stats.car_built_at,
        "propagator": type(search.prop).__name__,
        "clearance": [float(m) for m in config.margins(search.train)],
        "smoothing": smooth_info,
        "train_check": {
            "max_abs_phi": checked.max_abs_phi.tolist(),
            "min_clearance": checked.min_clearance,
            "wall_clearance": checked.wall_clearance,
            "max_tracking_error": checked.max_tracking_error,
            "max_lateral_error": checked.max_lateral_error,
            "max_heading_error": checked.max_heading_error,
            "goal_error": list(checked.goal_error),
            "speed": tracker.speed, "cusp_dwell": tracker.cusp_dwell,
        },
    }
    path = PlannedPath(start, tuple(segments), radius, headings, 0.01, info)
    t, _ = reference_times(path.segments, tracker.speed, tracker.cusp_dwell, path.s)
    path.headings = checked.headings_at(t)
    log.info("planned %.2f m, %d segments, %d cusps in %.3f s (%d expansions, %d steps)",
             path.length, len(segments), path.n_cusps, info["time"], stats.expansions,
             search.prop.steps)
    return path
