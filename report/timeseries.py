"""Figures over time: robot inputs and joint angles (the paper's Fig. 10/12), the last trailer's
tracking error, and the lateral wheel forces against the friction limit.

Speeds in m/s, yaw rates in deg/s, joint angles in degrees, lateral and longitudinal errors in
centimetres, forces in newtons.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from pushtrain.report.common import (
    C_DIST,
    C_ROBOT,
    C_SLIP,
    DIRECTION_BANDS,
    disturbance_mask,
    index_colorbar,
    intervals,
    legend_place,
    new_figure,
    output_path,
    save,
    series_colors,
    shade,
)
from pushtrain.report.data import check_data, col

__all__ = [
    "inputs_and_joints_figure",
    "plot_inputs_and_joints",
    "tracking_error_figure",
    "plot_tracking_error",
    "lateral_forces_figure",
    "plot_lateral_forces",
]


def _time_limits(ax, t: np.ndarray) -> None:
    ax.set_xlim(t[0], t[-1] if t[-1] > t[0] else t[0] + 1.0)


# ---------------------------------------------------------------------------------------------
# inputs and joint angles
# ---------------------------------------------------------------------------------------------
def inputs_and_joints_figure(data, n: int, phi_max_deg: float | None = None) -> Figure:
    """The figure of :func:`plot_inputs_and_joints`, unsaved.

    Line gids: ``v_cmd``, ``v0``, ``w_cmd``, ``w0``, ``phi{i}`` and ``phi_meas{i}`` (only where the
    measurement differs from the true angle), ``phi_max`` (the joint limit, with
    ``phi_max_deg``).
    """
    cols = ["t", "v0", "w0", "v_cmd", "w_cmd"] + [f"phi{i}" for i in range(1, n + 1)]
    n = check_data(data, n, cols)
    t = col(data, "t")
    fig = new_figure(8.0, 8.0)
    axes = fig.subplots(3, 1, sharex=True, height_ratios=(1.0, 1.0, 1.4))
    disturbance = intervals(t, disturbance_mask(data))
    for k, ax in enumerate(axes):
        shade(ax, disturbance, C_DIST, 0.12, label="disturbance (push/slide)" if k == 0 else None)
        ax.axhline(0.0, color="0.3", lw=0.6)
        ax.grid(True, lw=0.4, alpha=0.5)
    _robot_inputs(axes[0], axes[1], data, t)
    _joint_angles(fig, axes[2], data, t, n, phi_max_deg)
    _time_limits(axes[0], t)
    fig.suptitle(f"Robot inputs and joint angles ({n} trailer{'s' if n > 1 else ''})")
    return fig


def _robot_inputs(ax_v, ax_w, data, t: np.ndarray) -> None:
    """Commanded and actual robot speed [m/s] and yaw rate [deg/s]: the actual value wide and
    pale, the command thin, dashed and on top (they mostly coincide)."""
    ax_v.plot(t, col(data, "v0"), "-", color=C_ROBOT, lw=3.0, alpha=0.45, label="actual v0",
              gid="v0", zorder=2)
    ax_v.plot(t, col(data, "v_cmd"), "--", color="black", lw=1.0, label="command v_cmd",
              gid="v_cmd", zorder=3)
    ax_v.set_ylabel("v0 [m/s]")
    ax_v.set_title("Robot longitudinal speed (negative: pushing)", fontsize=10)
    ax_v.legend(loc=legend_place(ax_v, (0.3, 0.35)), fontsize=8)

    ax_w.plot(t, np.degrees(col(data, "w0")), "-", color=C_ROBOT, lw=3.0, alpha=0.45,
              label="actual w0", gid="w0", zorder=2)
    ax_w.plot(t, np.degrees(col(data, "w_cmd")), "--", color="black", lw=1.0,
              label="command w_cmd", gid="w_cmd", zorder=3)
    ax_w.set_ylabel("w0 [deg/s]")
    ax_w.set_title("Robot yaw rate", fontsize=10)
    ax_w.legend(loc=legend_place(ax_w, (0.3, 0.35)), fontsize=8)


def _joint_angles(fig, ax, data, t: np.ndarray, n: int, phi_max_deg: float | None) -> None:
    """True joint angles (solid) and, where they differ, the measured ones (dotted) [deg], and
    the joint limit +-``phi_max_deg`` (dashed red) where given."""
    if phi_max_deg:
        for sign in (1.0, -1.0):
            ax.axhline(sign * phi_max_deg, color="tab:red", ls="--", lw=1.0,
                       label=f"joint limit ±{phi_max_deg:g} deg" if sign > 0 else None,
                       gid="phi_max" if sign > 0 else None)
    colors = series_colors(n, categorical=n <= 12)
    names = data.dtype.names
    any_meas = False
    for i in range(1, n + 1):
        phi = np.degrees(col(data, f"phi{i}"))
        ax.plot(t, phi, "-", color=colors[i - 1], lw=1.4, label=f"phi{i}", gid=f"phi{i}")
        if f"phi_meas{i}" in names:
            meas = np.degrees(col(data, f"phi_meas{i}"))
            if np.nanmax(np.abs(meas - phi)) > 1e-6:
                any_meas = True
                ax.plot(t, meas, ":", color=colors[i - 1], lw=1.4, gid=f"phi_meas{i}")
    ax.set_ylabel("joint angle phi_i [deg]")
    ax.set_xlabel("time t [s]")
    ax.set_title("Joint angles phi_i = theta_(i-1) - theta_i" +
                 (" (solid: true, dotted: measured)" if any_meas else ""), fontsize=10)
    handles, labels = ax.get_legend_handles_labels()
    if any_meas:
        handles += [Line2D([], [], color="0.3", ls="-"), Line2D([], [], color="0.3", ls=":")]
        labels += ["true", "measured"]
    if n <= 12:
        ncol = max(1, min(4, (n + 3) // 4))
        rows = -(-len(labels) // ncol)
        ax.legend(handles, labels, loc=legend_place(ax, (0.15 * ncol, 0.07 * rows + 0.05)),
                  fontsize=8, ncol=ncol)
    else:
        index_colorbar(fig, ax, colors, "joint index i")


def plot_inputs_and_joints(data, n: int, out_path, phi_max_deg: float | None = None) -> Path:
    """Robot speed and yaw rate (command and actual) and the joint angles over time (Fig. 10/12).

    Speeds in m/s, yaw rates in deg/s, joint angles in degrees (true solid, measured dotted when
    the sensors differ), with the joint limit +-``phi_max_deg`` where given; disturbance
    intervals (push force, imposed slide) are shaded. Returns the written path.
    """
    path = output_path(out_path)
    return save(inputs_and_joints_figure(data, n, phi_max_deg), path)


# ---------------------------------------------------------------------------------------------
# tracking error
# ---------------------------------------------------------------------------------------------
def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a**2)))


_ERROR_SERIES = (("e_lat", 100.0, "e_lat [cm]", "tab:blue",
                  "lateral error (+: left of the reference heading)"),
                 ("e_lon", 100.0, "e_lon [cm]", "tab:purple",
                  "longitudinal error (+: ahead along the reference heading, toward the robot)"),
                 ("e_theta", 180.0 / math.pi, "e_theta [deg]", "tab:green",
                  "heading error theta_n - theta_d"))
"""(column, scale to the plotted unit, axis label, colour, panel title) of the three errors."""


def tracking_error_figure(data, n: int) -> Figure:
    """The figure of :func:`plot_tracking_error`, unsaved (line gids ``e_lat``, ``e_lon``,
    ``e_theta``; the direction bands are spans with gids ``direction+1`` (push), ``direction-1``
    (pull) and ``direction+0`` (rest))."""
    n = check_data(data, n, ["t", "e_lat", "e_lon", "e_theta", "direction"])
    t = col(data, "t")
    direction = np.rint(col(data, "direction"))
    fig = new_figure(8.0, 7.0)
    axes = fig.subplots(3, 1, sharex=True)
    disturbance = intervals(t, disturbance_mask(data))
    for ax, (name, scale, ylabel, color, what) in zip(axes, _ERROR_SERIES, strict=True):
        for value, band, label in DIRECTION_BANDS:
            shade(ax, intervals(t, direction == value), band, 1.0, label=label, zorder=0,
                  gid=f"direction{int(value):+d}")
        shade(ax, disturbance, C_DIST, 0.25, label="disturbance (push/slide)", zorder=0.5)
        e = col(data, name) * scale
        unit = ylabel.split("[")[1].rstrip("]")
        ax.plot(t, e, "-", color=color, lw=1.4, gid=name,
                label=f"RMS {_rms(e):.2f} {unit}, max |.| {np.max(np.abs(e)):.2f} {unit}, "
                      f"final {e[-1]:.2f} {unit}")
        ax.axhline(0.0, color="0.3", lw=0.6)
        ax.set_ylabel(ylabel)
        ax.set_title(what, fontsize=9)
        ax.grid(True, lw=0.4, alpha=0.5)
        ax.legend(handles=[ax.get_lines()[0]], loc=legend_place(ax, (0.45, 0.25)), fontsize=8)
    axes[-1].set_xlabel("time t [s]")
    _time_limits(axes[0], t)
    # only the bands that are drawn: a direction held for no time (the last sample's rest)
    # shades nothing and is not in the legend
    present = [(Patch(color=band), label) for value, band, label in DIRECTION_BANDS
               if sum(b - a for a, b in intervals(t, direction == value)) > 0.0]
    if disturbance:
        present.append((Patch(color=C_DIST, alpha=0.25), "disturbance (push/slide)"))
    if present:
        fig.legend(*zip(*present, strict=True), loc="outside lower center", ncol=len(present),
                   fontsize=8, title="background: reference direction", title_fontsize=8,
                   frameon=False)
    fig.suptitle("Tracking error of the last trailer (in the reference's frame)")
    return fig


def plot_tracking_error(data, n: int, out_path) -> Path:
    """Lateral and longitudinal errors [cm] and heading error [deg] of the last trailer over time,
    with the reference direction (push/pull/rest) as background bands. Returns the written path."""
    path = output_path(out_path)
    return save(tracking_error_figure(data, n), path)


# ---------------------------------------------------------------------------------------------
# lateral forces
# ---------------------------------------------------------------------------------------------
_SEPARATE_FORCE_PANELS = 4  # up to this many trailers: one panel each


def lateral_forces_figure(data, n: int) -> Figure:
    """The figure of :func:`plot_lateral_forces`, unsaved.

    Line gids: ``F_lat{i}`` (|F_lat_i| [N]) and ``F_lat_max{i}`` (friction limit); slip spans
    carry gid ``slip{i}``.
    """
    cols = ["t"] + [f"{b}{i}" for b in ("F_lat", "F_lat_max", "slipping") for i in range(1, n + 1)]
    n = check_data(data, n, cols)
    t = col(data, "t")
    force = [np.abs(col(data, f"F_lat{i}")) for i in range(1, n + 1)]
    limit = [col(data, f"F_lat_max{i}") for i in range(1, n + 1)]
    slips = [intervals(t, col(data, f"slipping{i}") > 0.5) for i in range(1, n + 1)]
    if n <= _SEPARATE_FORCE_PANELS:
        fig = _force_panels(t, force, limit, slips)
    else:
        fig = _force_overview(t, force, limit, slips)
    fig.suptitle("Lateral wheel forces against the friction limit μ (m + payload) g")
    return fig


def _peak(a: np.ndarray) -> float:
    """The largest finite value of ``a`` (0 where none is finite: a diverged run)."""
    finite = a[np.isfinite(a)]
    return float(finite.max()) if finite.size else 0.0


def _peak_ratio(force: np.ndarray, limit: np.ndarray) -> float:
    """Peak force over the peak friction limit (nan without a positive limit)."""
    lim = _peak(limit)
    return float(_peak(force) / lim) if lim > 0 else float("nan")


def _force_panels(t, force: list, limit: list, slips: list) -> Figure:
    """One panel per trailer: |F_lat_i| [N], its friction limit and the shaded slip intervals."""
    n = len(force)
    fig = new_figure(8.0, 1.2 + 2.0 * n)
    axes = np.atleast_1d(fig.subplots(n, 1, sharex=True, squeeze=False)[:, 0])
    for i, ax in enumerate(axes):
        for k, (a, b) in enumerate(slips[i]):
            ax.axvspan(a, b, color=C_SLIP, alpha=0.3, lw=0, gid=f"slip{i + 1}",
                       label="wheel slipping" if k == 0 else None)
        ax.plot(t, force[i], "-", color="tab:blue", lw=1.3, label=f"|F_lat,{i + 1}|",
                gid=f"F_lat{i + 1}")
        ax.plot(t, limit[i], "--", color="tab:red", lw=1.3,
                label=f"friction limit {_peak(limit[i]):.1f} N", gid=f"F_lat_max{i + 1}")
        ax.set_ylim(0.0, 1.15 * max(_peak(force[i]), _peak(limit[i]), 1e-9))
        ax.set_ylabel(f"|F_lat,{i + 1}| [N]")
        ax.set_title(f"trailer {i + 1}: peak {_peak(force[i]):.1f} N = "
                     f"{100 * _peak_ratio(force[i], limit[i]):.0f} % of the limit, "
                     f"{len(slips[i])} slip interval{'s' if len(slips[i]) != 1 else ''}",
                     fontsize=9)
        ax.grid(True, lw=0.4, alpha=0.5)
        ax.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time t [s]")
    _time_limits(axes[0], t)
    return fig


def _force_overview(t, force: list, limit: list, slips: list) -> Figure:
    """Many trailers: all |F_lat_i| [N] in one panel (colour by index) and a slip timeline."""
    n = len(force)
    fig = new_figure(8.5, 7.0)
    ax, ax_slip = fig.subplots(2, 1, sharex=True, height_ratios=(2.2, 1.0))
    colors = series_colors(n, categorical=False)
    for i in range(n):
        ax.plot(t, force[i], "-", color=colors[i], lw=1.0, gid=f"F_lat{i + 1}")
        ax.plot(t, limit[i], "--", color=colors[i] if np.ptp([_peak(v) for v in limit]) > 0
                else "tab:red", lw=1.2, gid=f"F_lat_max{i + 1}")
        for a, b in slips[i]:
            ax_slip.broken_barh([(a, max(b - a, 1e-9))], (i + 0.6, 0.8), color=C_SLIP,
                                gid=f"slip{i + 1}")
    ratios = [_peak_ratio(force[i], limit[i]) for i in range(n)]
    ax.set_ylabel("|F_lat,i| [N]")
    if np.isfinite(ratios).any():
        worst = int(np.nanargmax(ratios))
        peak = f"trailer {worst + 1}, {100 * ratios[worst]:.0f} % of its limit"
    else:
        peak = "none finite"
    ax.set_title(f"Lateral wheel force of each trailer (dashed: friction limit); highest "
                 f"peak: {peak}", fontsize=9)
    ax.grid(True, lw=0.4, alpha=0.5)
    index_colorbar(fig, ax, colors, "trailer index i")
    ax_slip.set_ylim(0.5, n + 0.5)
    ax_slip.set_ylabel("trailer i")
    ax_slip.set_title("wheel slipping intervals", fontsize=9)
    ax_slip.grid(True, lw=0.4, alpha=0.5)
    ax_slip.set_xlabel("time t [s]")
    _time_limits(ax, t)
    return fig


def plot_lateral_forces(data, n: int, out_path) -> Path:
    """|F_lat_i| of every trailer over time against its friction limit (dashed), with the slip
    intervals shaded (one panel per trailer up to 4 trailers, one panel and a slip timeline
    beyond). Returns the written path."""
    path = output_path(out_path)
    return save(lateral_forces_figure(data, n), path)
