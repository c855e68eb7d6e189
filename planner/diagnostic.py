"""Pictures of a planning problem: the train's bodies at given poses, and the PNG saved when a
plan fails (the map, start and goal, and the search's tree, best partial plan and failures)."""

from __future__ import annotations

import numpy as np

from pushtrain.facility.free_space import World

from .train import BodyFootprint, Train

__all__ = ["draw_poses", "place_label", "save_diagnostic"]


def draw_poses(ax, train: Train, x, y, theta, color="tab:blue", alpha=0.6, label=None):
    """Outline every body of ``train`` at positions ``x, y`` (n+1,) and headings (n+1,)."""
    for i, body in enumerate(train.bodies):
        c = body.corners(x[i], y[i], theta[i])
        ax.fill(c[:, 0], c[:, 1], facecolor="none", edgecolor=color, alpha=alpha,
                label=label if i == 0 else None)


_FAILURE_STYLE = {"collision": ("x", "red"), "self_collision": ("s", "darkorange"),
                  "joint_limit": ("^", "purple"), "pull_rule": ("v", "teal"),
                  "goal_missed": ("o", "brown")}


def save_diagnostic(path, world: World, start=None, goal=None, train: Train | None = None,
                    poses=None, title: str | None = None, marks=None,
                    failure: dict | None = None) -> None:
    """Save a PNG of the map with the last trailer at ``start`` and ``goal`` (x, y, theta).

    ``poses`` (N, 3) draws a path of the last trailer; ``marks`` is a list of (x, y, text)
    points to flag (collisions, ...). ``failure`` is the ``details`` of a PlanningError of the
    whole-train planner: its explored tree (``tree``: the last trailer's traces), the best
    partial plan (``closest``), the points where motions failed (``failure_points``, marked by
    kind and body) and the keep-out band of every clearance (``margins``: the free space shrunk
    by each margin, dashed). No pyplot: safe in headless processes.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 8))
    ax = fig.add_subplot()
    world.plot(ax)
    last = train.last if train is not None else BodyFootprint()
    if failure:
        _draw_failure(ax, world, failure, start)
        closest = failure.get("closest") or {}
        if train is not None and closest.get("x") is not None:
            draw_poses(ax, train, closest["x"], closest["y"], closest["headings"],
                       color="tab:blue", alpha=0.9, label="train at the best partial plan")
    for pose, color, name in ((start, "tab:green", "start"), (goal, "tab:red", "goal")):
        if pose is None:
            continue
        c = last.corners(*pose[:3])
        ax.fill(c[:, 0], c[:, 1], facecolor=color, alpha=0.4, edgecolor=color, label=name)
        ax.annotate("", xy=(pose[0] + 0.4 * np.cos(pose[2]), pose[1] + 0.4 * np.sin(pose[2])),
                    xytext=(pose[0], pose[1]), arrowprops={"arrowstyle": "->", "color": color})
    if poses is not None:
        poses = np.asarray(poses)
        ax.plot(poses[:, 0], poses[:, 1], "-", color="tab:blue", lw=1, label="last trailer")
    for x, y, text in marks or []:
        ax.plot([x], [y], "x", color="magenta", ms=10)
        ax.annotate(text, (x, y), color="magenta", fontsize=8)
    ax.legend(loc="best", fontsize=8)
    if title:
        ax.set_title(title, fontsize=9)
    fig.savefig(path, dpi=110)


def place_label(place: dict) -> tuple[str, str, str]:
    """(legend label, note beside it, colour) of a failure's place (a ``bottleneck``: the
    widest way's narrowest passage, or a corner or door too tight to turn in, whose width is
    the corridor's there): the width the map has against the width needed. The widest way's
    narrowest passage when it is wide enough is drawn grey and says so: what blocked the
    search is elsewhere."""
    what = place.get("what", "bottleneck")
    needed = place.get("needed")  # None: no steady turn of the radius fits
    need = "no steady turn fits" if needed is None else f"{needed:.2f} m needed"
    width = float(place["width"])
    if what == "bottleneck" and needed is not None and width >= needed:
        return (f"narrowest place of the widest way: {width:.2f} m wide, {need} (wide "
                "enough)", f"{width:.2f} m", "0.45")
    note = f"{width:.2f} m < {needed:.2f} m" if needed is not None and width < needed \
        else f"{width:.2f} m"
    return f"{what}: {width:.2f} m wide, {need}", note, "crimson"


def _draw_failure(ax, world: World, details: dict, start) -> None:
    """The search's tree, failure points, best partial plan, keep-out margins, the route
    through the building and the bottleneck on ``ax``."""
    route = details.get("route")
    if route and route.get("points"):
        xy = np.asarray(route["points"], dtype=float)
        ax.plot(xy[:, 0], xy[:, 1], "-", color="tab:green", lw=2.0, alpha=0.5,
                label=f"route ({route['length']:.1f} m)")
    # the place that blocks (the widest way's narrowest passage, or a corner too tight to
    # turn in) and, with a corner, the widest way's narrowest passage beside it
    for key, marker in (("bottleneck", "o"), ("widest", "D")):
        place = details.get(key)
        if place:
            label, note, color = place_label(place)
            ax.plot([place["x"]], [place["y"]], marker, ms=14 if marker == "o" else 9,
                    mfc="none", mew=2, color=color, label=label)
            ax.annotate(note, (place["x"], place["y"]), xytext=(8, 8),
                        textcoords="offset points", color=color, fontsize=8)
    for k, trace in enumerate(details.get("tree") or []):
        xy = np.asarray(trace, dtype=float)
        if xy.ndim == 2 and xy.shape[0] > 1:
            ax.plot(xy[:, 0], xy[:, 1], "-", color="0.6", lw=0.5,
                    label="explored (last trailer)" if k == 0 else None)
    for m in sorted(set(details.get("margins") or [])):
        if m <= 0.0:
            continue
        band = world.eroded(m)
        for k, poly in enumerate(getattr(band, "geoms", [band])):
            for ring in [poly.exterior, *poly.interiors]:
                xy = np.asarray(ring.coords)
                ax.plot(xy[:, 0], xy[:, 1], "--", color="tab:orange", lw=0.7,
                        label=f"keep-out {m:.3f} m" if k == 0 and ring is poly.exterior
                        else None)
    seen = set()
    for p in details.get("failure_points") or []:
        kind = p.get("kind", "collision").replace("verification_", "")
        marker, color = _FAILURE_STYLE.get(kind, ("x", "red"))
        label = kind.replace("_", " ") if kind not in seen else None
        seen.add(kind)
        ax.plot([p["x"]], [p["y"]], marker, color=color, ms=5, mfc="none", label=label)
    closest = details.get("closest")
    if closest and closest.get("segments") and start is not None:
        from pushtrain.core.reference import path_points
        from pushtrain.core.segment import Segment

        x, y = path_points(start, [Segment.from_dict(g) for g in closest["segments"]])
        ax.plot(x, y, "-", color="tab:blue", lw=2, label="best partial plan")
    if details.get("failure_points"):
        worst = {}
        for p in details["failure_points"]:
            if "body" in p:
                worst[p["body"]] = worst.get(p["body"], 0) + 1
        if worst:
            body = max(worst, key=worst.get)
            last = [p for p in details["failure_points"] if p.get("body") == body][-1]
            name = "robot" if body == 0 else f"trailer {body}"
            ax.annotate(f"{name} ({worst[body]} failures)", (last["x"], last["y"]),
                        color="red", fontsize=8)
