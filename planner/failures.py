"""Why the whole-train planner found no plan: its PlanningErrors, with numbers.

:func:`unreachable` (no way of the last trailer's width joins start and goal: "impossible here"
where the map proves it), :func:`widest_way` (what the map has on the way: the widest way's
narrowest place and the route's corner the turning train does not fit) and :func:`no_plan`
(a search that ended without a plan: what blocked the motions it tried, the budget, the
closest it came, and the data of ``planning_failure.png`` and the failure page).
"""

from __future__ import annotations

import math
import time

import numpy as np

from pushtrain.core.kinematics import body_positions
from pushtrain.errors import PlanningError

from .footprint import body_name
from .lattice import Search
from .passage import needed_half_width, tight_corners, widest_gap
from .route import find_route
from .train import Train
from .turnable import turning_bands

__all__ = ["TRANSIENT_CUT", "no_plan", "unreachable", "widest_way"]

TRANSIENT_CUT = 0.1
"""Metres the followers cut inside a steady arc's band while entering it (0.1-0.2 m): a corner
a steady turn fits with less to spare is named in a failure."""


def unreachable(field, train: Train, start, goal, half_width: float, impossible: bool,
                 grid: float | None = None) -> PlanningError:
    """The PlanningError of a mission whose goal no way of the train's width reaches: where the
    widest way between start and goal is narrowest (:func:`~pushtrain.planner.passage.widest_gap`)
    against the width the train needs (``half_width`` [m]: the last trailer's disc and
    clearance). ``impossible``: :func:`~pushtrain.planner.passage.passable` said no (every
    way narrower than that by more than half a cell diagonal: "impossible here"); else
    ``grid`` [m] names the heuristic's grid, which (and not the map) found no way."""
    width = train.last.width
    gap = widest_gap(field, start, goal, half_width)
    ends = (f"from the start ({start[0]:.2f}, {start[1]:.2f}) to the goal ({goal[0]:.2f}, "
            f"{goal[1]:.2f})")
    impossible = impossible or gap is None
    if gap is None:
        text = (f"no free way at all joins the start ({start[0]:.2f}, {start[1]:.2f}) and the goal "
                f"({goal[0]:.2f}, {goal[1]:.2f}): they lie in separate parts of the map")
        where = tuple(goal[:2])
    else:
        text = (f"the last trailer ({width:.2f} m wide, clearance "
                f"{half_width - needed_half_width(train, 0.0):.3f} m, leading the train into "
                f"every place it goes) needs passages {2 * half_width:.2f} m wide, and every way "
                f"{ends} narrows to {gap.width:.2f} m or less: the widest way's narrowest place "
                f"is at ({gap.x:.2f}, {gap.y:.2f})")
        if not impossible:
            text += (f", within one map cell ({field.resolution:.3f} m) of what it needs, and "
                     f"the planner's {grid or field.resolution:.3f} m grid finds no way through "
                     "it")
        where = (gap.x, gap.y)
    details = {"constraint": "map", "impossible": impossible,
               "bottleneck": None if gap is None else {
                   **gap.to_dict(), "what": "bottleneck"}}
    head = "impossible here: " if impossible else "no way found: "
    return PlanningError("unreachable", head + text, where=where, details=details)


def widest_way(field, train: Train, start, goal, config, margins, route) -> dict:
    """What the map has on the way (plain data for :func:`no_plan`): the widest way's
    narrowest place against what the last trailer needs (``bottleneck``), and the route's
    corner the train's swept band does not fit, if any (``corner``, see
    :mod:`~pushtrain.planner.passage`); ``text`` says both with numbers."""
    gap = widest_gap(field, start, goal, needed_half_width(train, margins[-1]))
    out = {"bottleneck": None if gap is None else {**gap.to_dict(), "what": "bottleneck"},
           "corner": None, "text": ""}
    if gap is None:
        return out
    out["text"] = (f". The widest way's narrowest place, at ({gap.x:.2f}, {gap.y:.2f}), is "
                   f"{gap.width:.2f} m wide; the last trailer needs {gap.needed:.2f} m (its width "
                   "and clearance)")
    if route is None:
        route = find_route(field, start, goal, 0.5 * train.last.width + float(margins[-1]))
    if route is None:
        return out
    band, tightest = turning_bands(train, config, margins)
    corners = tight_corners(route, field, band, tightest)
    # a corner a steady turn does not fit, or fits with less to spare than the followers cut
    # inside entering an arc (0.1-0.2 m, not in the steady band): the place to look at
    if corners and corners[0].width < corners[0].needed + TRANSIENT_CUT:
        corner = corners[0]
        out["corner"] = corner.to_dict()
        out["bottleneck"] = {**corner.to_dict(), "what": corner.what}
        out["widest"] = {**gap.to_dict(), "what": "bottleneck"}
        text = (" " if corner.door is None else ": ") + corner.text()
        out["text"] += (f". The train cannot turn on the planner's arcs{text}"
                        if corner.too_tight else
                        f". The tightest turn leaves {corner.width - corner.needed:.2f} m to "
                        f"spare on the planner's arcs, less than the followers cut inside "
                        f"entering an arc ({TRANSIENT_CUT:.2f} m or more){text}")
    return out


def no_plan(search: Search, train: Train, goal, config, margins, phi_limit,
             t_begin, way: dict) -> PlanningError:
    """The PlanningError of a search that found nothing: what blocked it, with numbers;
    ``way`` is :func:`widest_way`'s."""
    stats = search.stats
    f = stats.failures
    tried = stats.rollouts
    parts = []
    if f["collision"]:
        body, count = stats.bodies.most_common(1)[0]
        where = [p for p in stats.points if p["kind"] == "collision" and p["body"] == body]
        near = f" near ({where[-1]['x']:.2f}, {where[-1]['y']:.2f})" if where else ""
        parts.append(f"{f['collision']} hit a wall within their clearance (most often the "
                     f"{body_name(body)}, {count} times{near}; clearance "
                     f"{_margins_text(margins)})")
    if f["reference"]:
        parts.append(f"{f['reference']} were refused before simulating: the last trailer's "
                     "own footprint on the reference misses its clearance")
    if f["joint_limit"]:
        parts.append(f"{f['joint_limit']} bent a joint beyond {math.degrees(phi_limit):.1f} deg "
                     f"(phi_max {math.degrees(train.phi_max):.1f} deg minus the joint margin "
                     f"{math.degrees(config.joint_margin):.1f} deg)")
    if f["self_collision"]:
        parts.append(f"{f['self_collision']} folded the train onto itself")
    if f["pull_rule"]:
        parts.append(f"{f['pull_rule']} pull{'s were' if f['pull_rule'] != 1 else ' was'} not "
                     "started because the chain was bent "
                     f"more than {math.degrees(config.pull_max_phi):.1f} deg (pull rule)")
    if f["goal_missed"]:
        straight = ("" if config.goal_max_phi is None else
                    f", every joint within {math.degrees(config.goal_max_phi):.1f} deg")
        g = config.goal_fraction
        parts.append(f"{f['goal_missed']} connections to the goal ended outside {g:g} of its "
                     f"tolerance ({g * config.goal_tolerance[0]:.3f} m, "
                     f"{math.degrees(g * config.goal_tolerance[1]):.2f} deg{straight})")
    verified = sum(v for k, v in f.items() if k.startswith("verification_"))
    if verified:
        parts.append(f"{verified} paths found failed the exact verification")
    blocked = "; ".join(parts) if parts else "nothing was tried"
    elapsed = time.perf_counter() - t_begin
    if stats.cut == "budget":
        reason, head = "budget_exhausted", (
            f"no plan within the budget of {config.budget_steps(train.n)} simulated control "
            f"steps ({_budget_text(config)}; {stats.expansions} expansions; a larger "
            "planner.time_budget searches further)")
    elif stats.cut == "deadline":
        reason, head = "budget_exhausted", (
            f"no plan before the wall-clock safety cap of {config.wall_cap():g} s stopped the "
            f"search ({search.prop.steps} of {config.budget_steps(train.n)} steps of "
            f"{_budget_text(config)} done, {stats.expansions} expansions; this result depends "
            "on the machine's speed: a faster or less loaded machine, or a larger "
            "planner.time_budget, does more)")
    else:
        reason, head = "unreachable", (
            f"no plan: the search ran out of states after {stats.expansions} expansions "
            f"({elapsed:.2f} s)")
    closest = search.closest
    details = {
        "constraint": _main_constraint(stats),
        "time_capped": stats.cut == "deadline",
        "expansions": stats.expansions, "steps": search.prop.steps,
        "failures": dict(f), "failure_points": stats.points,
        "margins": [float(m) for m in margins],
        "tree": [n.trace.tolist() for n in search.nodes if n.trace is not None][:3000],
        "route": None if search.route is None else search.route.to_dict(),
        "closest": {"segments": [g.to_dict() for g in closest.path_segments()],
                    "pose": list(closest.cursor.pose), "remaining": closest.h,
                    **_train_at(closest.state, train)},
    }
    details.update({k: v for k, v in way.items() if k != "text"})
    route = ""
    if search.route is not None:
        route = f". The route through the building is {search.route.length:.1f} m"
    route += way["text"]
    corner = way.get("corner")
    return PlanningError(reason, f"{head}. Of {tried} motions tried: {blocked}. The closest "
                         f"the last trailer came was {closest.h:.2f} m of path from the goal"
                         f"{route}",
                         where=(corner["x"], corner["y"]) if corner else tuple(goal[:2]),
                         details=details)


def _budget_text(config) -> str:
    if config.time_budget is None:
        return f"the default budget, about {config.budget_seconds():g} s"
    return f"time_budget {config.time_budget:g} s"


def _train_at(state, train: Train) -> dict:
    """Every body's axle midpoint and heading in ``state`` (plain lists, for the picture)."""
    z = np.array([state.z])
    x, y = body_positions(z[:, 0], z[:, 1], z[:, 2:], train.geometry)
    return {"x": x[0].tolist(), "y": y[0].tolist(), "headings": z[0, 2:].tolist()}


def _main_constraint(stats) -> str:
    kinds = {k: v for k, v in stats.failures.items() if k != "reference"}
    if stats.cut is not None:
        return "budget"
    if not kinds:
        return "map"
    return max(sorted(kinds), key=lambda k: kinds[k])


def _margins_text(margins) -> str:
    values = sorted(set(float(m) for m in margins))
    if len(values) == 1:
        return f"{values[0]:.3f} m"
    return ", ".join(f"{body_name(i)} {m:.3f} m" for i, m in enumerate(margins))
