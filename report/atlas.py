"""The pictures of a facility atlas (:mod:`pushtrain.studies.atlas`): ``atlas.png``, the map
with the stations and each pair's way coloured by the most trailers that made it, the
bottleneck of each failing pair marked; ``matrix.png``, stations x stations with that number in
each cell. Agg canvas, no pyplot."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.colors import BoundaryNorm
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from pushtrain.report.common import new_figure, save

__all__ = ["atlas_figure", "matrix_figure", "save_figure"]


def _scale(top: int):
    """Colours of 0..top trailers: grey for 0, then light to dark."""
    cmap = colormaps["viridis_r"].resampled(top + 1)
    colors = ["#9a9a9a"] + [cmap(k) for k in range(1, top + 1)]
    return colors, BoundaryNorm(np.arange(-0.5, top + 1.5), top + 1)


def atlas_figure(world, stations: list[dict], answers: list[dict], top: int) -> Figure:
    """The map, the stations (a dot and an arrow: the way the train is pushed) and the way of
    each pair (its planned path, or its route where it failed) coloured by ``max_trailers``;
    a red ring at each failing pair's bottleneck."""
    fig = new_figure(9.0, 7.0, fixed_aspect=True)
    ax = fig.add_subplot()
    world.plot(ax)
    colors, _ = _scale(top)
    for a in sorted(answers, key=lambda a: a["max_trailers"]):
        shape = a.get("shape") or {}
        xy = shape.get("path") or shape.get("route")
        if xy:
            xy = np.asarray(xy, dtype=float)
            ax.plot(xy[:, 0], xy[:, 1], "-", color=colors[a["max_trailers"]],
                    lw=1.2 + 0.5 * a["max_trailers"], alpha=0.7, zorder=3)
        b = (a.get("failure") or {}).get("bottleneck")
        if b:
            ax.plot([b["x"]], [b["y"]], "o", ms=14, mfc="none", mec="crimson", mew=2, zorder=5)
    for s in stations:
        th = math.radians(s["theta_deg"]) + math.pi  # pushed away from the robot
        ax.annotate("", xy=(s["x"] + 0.6 * math.cos(th), s["y"] + 0.6 * math.sin(th)),
                    xytext=(s["x"], s["y"]),
                    arrowprops={"arrowstyle": "->", "color": "black", "lw": 1.5}, zorder=6)
        ax.plot([s["x"]], [s["y"]], "o", color="black", ms=6, zorder=6)
        ax.annotate(s["name"], (s["x"], s["y"]), xytext=(6, 6), textcoords="offset points",
                    fontsize=9, weight="bold", zorder=7,
                    bbox={"boxstyle": "round,pad=0.15", "fc": "white", "alpha": 0.8,
                          "lw": 0})
    handles = [Line2D([], [], color=colors[k], lw=1.2 + 0.5 * k,
                      label=f"most trailers {k}" if k else "not reached (0)")
               for k in range(top + 1)]
    handles.append(Line2D([], [], ls="", marker="o", ms=10, mfc="none", mec="crimson",
                          mew=2, label="bottleneck of a failing pair"))
    handles.append(Line2D([], [], ls="", marker="o", color="black", label="station (arrow: "
                          "the way it is pushed)"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8,
              frameon=False, title="way of each pair\n(planned path, or route)",
              title_fontsize=8)
    ax.set_title("Facility atlas: the most trailers that reach each station")
    return fig


def matrix_figure(names: list[str], answers: list[dict], top: int) -> Figure:
    """Stations x stations: the most trailers from the row's station to the column's."""
    index = {n: k for k, n in enumerate(names)}
    grid = np.full((len(names), len(names)), np.nan)
    for a in answers:
        grid[index[a["from"]], index[a["to"]]] = a["max_trailers"]
    colors, norm = _scale(top)
    from matplotlib.colors import ListedColormap

    size = 1.2 + 0.7 * len(names)
    fig = new_figure(size + 1.6, size)
    ax = fig.add_subplot()
    image = ax.imshow(np.ma.masked_invalid(grid), cmap=ListedColormap(colors), norm=norm)
    for i in range(len(names)):
        for j in range(len(names)):
            text = "-" if i == j else ("" if math.isnan(grid[i, j]) else f"{int(grid[i, j])}")
            dark = not math.isnan(grid[i, j]) and grid[i, j] >= 0.6 * top
            ax.text(j, i, text, ha="center", va="center", fontsize=11,
                    color="white" if dark else "black")
    ax.set_xticks(range(len(names)), names, rotation=40, ha="right")
    ax.set_yticks(range(len(names)), names)
    ax.set_xlabel("to")
    ax.set_ylabel("from")
    bar = fig.colorbar(image, ax=ax, ticks=range(top + 1), shrink=0.8)
    bar.set_label("most trailers reaching the goal")
    ax.set_title("Most trailers, from station to station")
    return fig


def save_figure(fig: Figure, path) -> Path:
    """Save ``fig`` atomically (PNG)."""
    return save(fig, Path(path))
