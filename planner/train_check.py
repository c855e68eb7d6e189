"""Whole-train check: integrate the chain along a planned path and test every body.

The planner plans the last trailer only. Here the motion of all bodies is reconstructed:

Pushing stretches (trailer leads)
    The last trailer follows the planned path exactly and the other headings follow from the
    inverse velocity map of :mod:`pushtrain.cosim.kinematics` (``heading_rates_from_last``):
    for travel speed |v| = 1, ``v_n = -1``, ``w_n = curvature`` and
    ``d(theta)/ds = heading_rates_from_last(theta, v_n, w_n)`` (RK4). This direction is stable.

Pulling stretches (robot leads)
    Making the last trailer follow a pulling segment exactly is the unstable direction of the
    chain: from a straight 3-trailer chain (D = 0.52 m) a 1 deg pulling arc followed by 1 m of
    straight pulling already drives a joint past 100 deg, so that model would reject almost
    every plan with a cusp. Instead the robot leads: it pursues the planned curve (pure
    pursuit with look-ahead ``lookahead`` [m] on the curve extended straight past its end) and
    the trailers are towed (``forward_velocities``, stable). The stretch ends when the last
    trailer's progress along the planned curve reaches its end; the largest distance of the
    last trailer from the planned curve and its end error are reported, and an end error above
    ``pull_tolerance`` (or a heading error above ``pull_heading_tolerance``) is a failure. The next pushing stretch starts from the planned cusp
    pose with the headings the towed chain arrived with. The co-simulation master's
    robot-led controller is free to differ; this model only asks whether the train can be
    pulled along the curve at all.

Every body's rectangle is tested against the free space shrunk by a margin (shapely,
vectorized) and every |phi_i| against the train's ``phi_max``. Samples are refined until no
corner of any body moves more than ``resolution`` between two checked samples.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import shapely

from pushtrain.cosim.kinematics import ChainGeometry, joint_angles
from pushtrain.cosim.reference import PUSH, Segment

from .path import dense_samples
from .world import Train, World

__all__ = [
    "TrainCheckResult",
    "integrate_headings",
    "body_positions_along",
    "check_train",
    "chain_heading_rates",
]

log = logging.getLogger(__name__)


def chain_heading_rates(geometry: ChainGeometry):
    """A fast scalar version of ``kinematics.heading_rates_from_last`` for one geometry.

    Returns ``f(theta, v_n, w_n) -> list`` of d(theta_i)/dt [rad/s], i = 0..n. Same recursion
    (v_{i-1} = c v_i + F_i s w_i, w_{i-1} = (s v_i - F_i c w_i) / R_{i-1}); the tests compare it
    with :func:`pushtrain.cosim.kinematics.heading_rates_from_last`.
    """
    front = [float(a) for a in geometry.front]
    rear = [float(a) for a in geometry.rear]
    n = geometry.n

    def rates(theta, v_n: float, w_n: float):
        w = [0.0] * (n + 1)
        v, w[n] = v_n, w_n
        for i in range(n, 0, -1):
            phi = theta[i - 1] - theta[i]
            c, s = math.cos(phi), math.sin(phi)
            f = front[i - 1]
            v, w[i - 1] = c * v + f * s * w[i], (s * v - f * c * w[i]) / rear[i - 1]
        return w

    return rates


def integrate_headings(
    s: np.ndarray,
    interval_segment: np.ndarray,
    segments: Sequence[Segment],
    theta0: Sequence[float],
    geometry: ChainGeometry,
) -> np.ndarray:
    """Headings of all bodies at the samples ``s`` [m] (RK4 over each sample interval).

    ``theta0`` (n+1,) are the start headings [rad]; returns (N, n+1) [rad], continuous.
    """
    rates = chain_heading_rates(geometry)
    n1 = geometry.n + 1
    out = np.empty((s.size, n1))
    th = [float(a) for a in theta0]
    out[0] = th
    sigma = [-float(g.direction) for g in segments]
    kappa = [float(g.curvature) for g in segments]
    ds_all = np.diff(s)
    for k in range(s.size - 1):
        j = interval_segment[k]
        v, w, h = sigma[j], kappa[j], float(ds_all[k])
        k1 = rates(th, v, w)
        k2 = rates([a + 0.5 * h * b for a, b in zip(th, k1)], v, w)
        k3 = rates([a + 0.5 * h * b for a, b in zip(th, k2)], v, w)
        k4 = rates([a + h * b for a, b in zip(th, k3)], v, w)
        th = [a + h / 6.0 * (b1 + 2 * b2 + 2 * b3 + b4) for a, b1, b2, b3, b4 in zip(th, k1, k2, k3, k4)]
        out[k + 1] = th
    return out


def body_positions_along(poses: np.ndarray, headings: np.ndarray, geometry: ChainGeometry):
    """Positions [m] of every body from the last trailer's poses (N, 3) and headings (N, n+1).

    Vectorized form of ``kinematics.body_positions_from_last``: P_{i-1} = P_i + F_i e_i +
    R_{i-1} e_{i-1}. Returns ``(x, y)``, each (N, n+1).
    """
    c, s = np.cos(headings), np.sin(headings)
    # step k (k = 0..n-1): vector from P_{k+1} to P_k
    step_x = geometry.front * c[:, 1:] + geometry.rear * c[:, :-1]
    step_y = geometry.front * s[:, 1:] + geometry.rear * s[:, :-1]
    x = np.empty_like(headings)
    y = np.empty_like(headings)
    x[:, -1], y[:, -1] = poses[:, 0], poses[:, 1]
    x[:, :-1] = poses[:, :1] + np.cumsum(step_x[:, ::-1], axis=1)[:, ::-1]
    y[:, :-1] = poses[:, 1:2] + np.cumsum(step_y[:, ::-1], axis=1)[:, ::-1]
    return x, y


@dataclass
class TrainCheckResult:
    """Outcome of :func:`check_train`.

    Attributes
    ----------
    ok : bool
        Every body inside the shrunk free space and every |phi_i| <= phi_max at every sample.
    s, poses, headings, x, y : arrays
        Samples [m], last-trailer poses (N, 3), headings (N, n+1) [rad], body positions (N, n+1).
    max_abs_phi : (n,) array
        Largest |phi_i| along the path [rad].
    min_clearance : float
        Smallest distance [m] of any body to the blocked space (negative: overlap depth bound).
    pulls : list of dict
        Per pulling stretch: ``max_deviation`` and ``end_error`` [m] of the towed last trailer
        from the planned curve.
    failure : dict or None
        First failure: ``kind`` ("collision", "joint_limit" or "pull_deviation"), ``body`` (0 robot .. n),
        ``index``, ``s`` [m], ``x``, ``y`` [m] (body position, or the overlap point for
        collisions), ``phi`` [rad] for joint failures.
    """

    ok: bool
    s: np.ndarray
    poses: np.ndarray
    headings: np.ndarray
    x: np.ndarray
    y: np.ndarray
    max_abs_phi: np.ndarray
    min_clearance: float
    failure: dict | None = None
    collisions: list = field(default_factory=list)
    pulls: list = field(default_factory=list)


def _pull_stretch(theta0, last_xy, curve, length, geometry, ds, lookahead):
    """Tow the chain with the robot pursuing ``curve`` (M, 2) until the last trailer's progress
    along its first ``length`` metres reaches the end.

    Returns (x (K, n+1), y (K, n+1), theta (K, n+1), progress (K,)) of the samples after the
    first one (which equals the given state).
    """
    n = geometry.n
    seg = np.diff(curve, axis=0)
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    cum = np.concatenate(([0.0], np.cumsum(seg_len)))
    theta = np.asarray(theta0, dtype=float).copy()
    xs, ys = body_positions_from_last_vec(last_xy, theta, geometry)
    x0, y0 = xs[0], ys[0]
    front, rear = geometry.front, geometry.rear
    out_x, out_y, out_t, out_p = [], [], [], []

    def project(px, py, lo_idx):
        d = np.hypot(curve[:, 0] - px, curve[:, 1] - py)
        k = int(np.argmin(d))
        # refine on the neighbouring polyline pieces
        best_s, best_d = cum[k], d[k]
        for j in (k - 1, k):
            if 0 <= j < seg_len.size and seg_len[j] > 0.0:
                u = ((px - curve[j, 0]) * seg[j, 0] + (py - curve[j, 1]) * seg[j, 1]) / seg_len[j] ** 2
                u = min(1.0, max(0.0, u))
                qx, qy = curve[j, 0] + u * seg[j, 0], curve[j, 1] + u * seg[j, 1]
                dd = math.hypot(px - qx, py - qy)
                if dd < best_d:
                    best_s, best_d = cum[j] + u * seg_len[j], dd
        return best_s, best_d

    def rates(state):
        x0_, y0_ = state[0], state[1]
        th = state[2:]
        s_r, _ = project(x0_, y0_, 0)
        target = s_r + lookahead
        gx = float(np.interp(target, cum, curve[:, 0]))
        gy = float(np.interp(target, cum, curve[:, 1]))
        alpha = math.atan2(gy - y0_, gx - x0_) - th[0]
        alpha = (alpha + math.pi) % (2.0 * math.pi) - math.pi
        w0 = 2.0 * math.sin(alpha) / lookahead
        # towing: forward velocity map from the robot (v0 = 1)
        w = np.empty(n + 1)
        v, w[0] = 1.0, w0
        for i in range(1, n + 1):
            phi = th[i - 1] - th[i]
            c, s = math.cos(phi), math.sin(phi)
            v, w[i] = c * v + rear[i - 1] * s * w[i - 1], (s * v - rear[i - 1] * c * w[i - 1]) / front[i - 1]
        return np.concatenate(([math.cos(th[0]), math.sin(th[0])], w))

    state = np.concatenate(([x0, y0], theta))
    max_steps = int(10 * (length + 4.0 * (front.sum() + rear.sum())) / ds) + 10
    for _ in range(max_steps):
        k1 = rates(state)
        k2 = rates(state + 0.5 * ds * k1)
        state = state + ds * k2
        th = state[2:]
        bx, by = body_positions_vec(state[0], state[1], th, geometry)
        prog, _ = project(bx[-1], by[-1], 0)
        out_x.append(bx), out_y.append(by), out_t.append(th.copy()), out_p.append(prog)
        if prog >= length - 1e-9:
            break
    return np.array(out_x), np.array(out_y), np.array(out_t), np.array(out_p)


def body_positions_vec(x0, y0, theta, geometry):
    """Positions of bodies 0..n from the robot centre (as ``kinematics.body_positions``)."""
    c, s = np.cos(theta), np.sin(theta)
    step_x = -geometry.rear * c[:-1] - geometry.front * c[1:]
    step_y = -geometry.rear * s[:-1] - geometry.front * s[1:]
    return (x0 + np.concatenate(([0.0], np.cumsum(step_x))),
            y0 + np.concatenate(([0.0], np.cumsum(step_y))))


def body_positions_from_last_vec(last_xy, theta, geometry):
    """Positions of bodies 0..n from the last trailer's position and all headings."""
    x, y = body_positions_vec(0.0, 0.0, theta, geometry)
    return x + (last_xy[0] - x[-1]), y + (last_xy[1] - y[-1])


def _simulate(start, segments, theta0, geometry, step, lookahead):
    """Samples of the whole train along the path: (s, last-trailer poses, headings, x, y,
    pull_info, jump) where s is the last trailer's planned progress [m] and ``jump`` marks the
    samples re-anchored to the planned cusp pose after a pulling stretch."""
    s_all, poses_all, interval_segment = dense_samples(start, segments, step)
    n1 = geometry.n + 1
    # stretches: maximal runs of intervals with the same direction
    direction = np.array([segments[j].direction for j in interval_segment])
    bounds = np.concatenate(([0], np.flatnonzero(np.diff(direction) != 0) + 1, [direction.size]))
    S, P, TH, X, Y = [np.array([0.0])], [poses_all[:1]], [np.asarray(theta0, float)[None, :]], [], []
    x_first, y_first = body_positions_from_last_vec(poses_all[0, :2], np.asarray(theta0, float), geometry)
    X.append(x_first[None, :]), Y.append(y_first[None, :])
    pull_info = []
    jumps = [np.array([False])]
    theta = np.asarray(theta0, dtype=float)
    for a, b in zip(bounds[:-1], bounds[1:]):
        # samples a..b (interval a starts at sample a, interval b-1 ends at sample b)
        if direction[a] == PUSH:
            sub_s = s_all[a:b + 1]
            th = integrate_headings(sub_s, interval_segment[a:b], segments, theta, geometry)
            th[:, -1] = poses_all[a:b + 1, 2] + (th[0, -1] - poses_all[a, 2])
            x, y = body_positions_along(poses_all[a:b + 1], th, geometry)
            S.append(sub_s[1:]), P.append(poses_all[a + 1:b + 1]), TH.append(th[1:])
            X.append(x[1:]), Y.append(y[1:])
            jumps.append(np.zeros(b - a, dtype=bool))
            theta = th[-1]
        else:
            length = s_all[b] - s_all[a]
            curve = poses_all[a:b + 1, :2]
            end_dir = np.array([np.cos(poses_all[b, 2]), np.sin(poses_all[b, 2])])
            ext = curve[-1] + np.outer(np.linspace(step, 6.0 * lookahead + 4.0, 200), end_dir)
            full = np.vstack([curve, ext])
            start_xy = P[-1][-1, :2] if len(P) else poses_all[a, :2]
            x, y, th, prog = _pull_stretch(theta, start_xy, full, length, geometry,
                                           step, lookahead)
            s_sub = s_all[a:b + 1] - s_all[a]
            px = np.interp(prog, s_sub, poses_all[a:b + 1, 0])
            py = np.interp(prog, s_sub, poses_all[a:b + 1, 1])
            dev = np.hypot(x[:, -1] - px, y[:, -1] - py)
            end_err = float(np.hypot(x[-1, -1] - poses_all[b, 0], y[-1, -1] - poses_all[b, 1]))
            pull_info.append({"s_start": float(s_all[a]), "s_end": float(s_all[b]),
                              "max_deviation": float(dev.max()), "end_error": end_err,
                              "end_heading_error": float(th[-1, -1] - poses_all[b, 2])})
            last_pose = np.column_stack([x[:, -1], y[:, -1], th[:, -1]])
            S.append(s_all[a] + prog), P.append(last_pose), TH.append(th), X.append(x), Y.append(y)
            # continue from the planned cusp pose with the towed chain's headings
            theta = th[-1] - th[-1, -1] + poses_all[b, 2]
            x_re, y_re = body_positions_from_last_vec(poses_all[b, :2], theta, geometry)
            S.append(np.array([s_all[b]])), P.append(poses_all[b:b + 1]), TH.append(theta[None, :])
            X.append(x_re[None, :]), Y.append(y_re[None, :])
            jumps.append(np.zeros(x.shape[0], dtype=bool)), jumps.append(np.array([True]))
    return (np.concatenate(S), np.vstack(P), np.vstack(TH), np.vstack(X), np.vstack(Y), pull_info,
            np.concatenate(jumps))


def check_train(
    world: World,
    train: Train,
    start: Sequence[float],
    segments: Sequence[Segment],
    start_headings: Sequence[float] | None = None,
    margin: float = 0.0,
    resolution: float = 0.01,
    free_eroded=None,
    lookahead: float = 1.0,
    pull_tolerance: float = 0.25,
    pull_heading_tolerance: float = 0.2,
) -> TrainCheckResult:
    """Reconstruct the train's motion along the path and test footprints and joint limits.

    Parameters
    ----------
    world, train : World, Train
    start : (x, y, theta)
        Last trailer's start pose [m, m, rad], chain convention.
    segments : sequence of Segment
    start_headings : (n+1,) or None
        Start headings [rad]; None is a straight chain (all equal to ``start[2]``).
    margin : float
        Clearance [m] every body must keep from the blocked space.
    resolution : float
        Largest corner displacement [m] of any body between checked samples.
    free_eroded : shapely geometry or None
        Precomputed ``world.eroded(margin)``.
    lookahead : float
        Pure-pursuit look-ahead [m] of the robot on pulling stretches.
    pull_tolerance : float
        Largest allowed distance [m] of the last trailer from the planned end of a pulling
        stretch.
    pull_heading_tolerance : float
        Largest allowed heading error [rad] of the last trailer there.
    """
    n = train.n
    theta0 = (
        np.full(n + 1, float(start[2]))
        if start_headings is None
        else np.asarray(start_headings, dtype=float).reshape(-1)
    )
    if theta0.size != n + 1:
        raise ValueError(f"start_headings has {theta0.size} entries; need n + 1 = {n + 1}")
    region = world.eroded(margin) if free_eroded is None else free_eroded
    step = float(resolution)
    for _attempt in range(4):
        s, poses, headings, x, y, pull_info, jump = _simulate(
            start, segments, theta0, train.geometry, step, lookahead
        )
        corners = np.stack(
            [b.corners(x[:, i], y[:, i], headings[:, i]) for i, b in enumerate(train.bodies)], axis=1
        )  # (N, n+1, 4, 2)
        move = np.linalg.norm(np.diff(corners, axis=0), axis=-1)  # (N-1, n+1, 4)
        # a re-anchoring jump after a pulling stretch is not motion: ignore those intervals
        moving = ~jump[1:]
        move = move[moving].max() if moving.any() else 0.0
        if move <= resolution * (1.0 + 1e-9):
            break
        step *= 0.95 * resolution / move
    else:
        log.warning("train check: corner motion %.4f m per sample exceeds %.4f m", move, resolution)
    polys = shapely.polygons(corners)
    inside = shapely.contains(region, polys)  # (N, n+1)
    phi = joint_angles(headings)  # (N, n)
    abs_phi = np.abs(phi)
    max_abs_phi = abs_phi.max(axis=0)
    clear = shapely.distance(region.boundary, polys)
    clear = np.where(inside, clear, -clear)
    failure = None
    collisions = [(int(k), int(i)) for k, i in zip(*np.nonzero(~inside))]
    k_coll = np.flatnonzero(~inside.all(axis=1))
    k_joint = np.flatnonzero((abs_phi > train.phi_max).any(axis=1))
    if k_coll.size and (not k_joint.size or k_coll[0] <= k_joint[0]):
        k = int(k_coll[0])
        i = int(np.flatnonzero(~inside[k])[0])
        outside = polys[k, i].difference(region)
        point = outside.representative_point() if not outside.is_empty else polys[k, i].centroid
        failure = {
            "kind": "collision", "body": i, "index": k, "s": float(s[k]),
            "x": float(point.x), "y": float(point.y),
            "body_x": float(x[k, i]), "body_y": float(y[k, i]), "theta": float(headings[k, i]),
        }
    elif k_joint.size:
        k = int(k_joint[0])
        j = int(np.argmax(abs_phi[k]))
        failure = {
            "kind": "joint_limit", "body": j + 1, "index": k, "s": float(s[k]),
            "x": float(x[k, j + 1]), "y": float(y[k, j + 1]), "phi": float(phi[k, j]),
        }
    for info in pull_info:
        bad = info["end_error"] > pull_tolerance or abs(info["end_heading_error"]) > pull_heading_tolerance
        if bad and (failure is None or info["s_end"] <= failure["s"]):
            k = int(np.searchsorted(s, info["s_end"]))
            failure = {
                "kind": "pull_deviation", "body": n, "index": k, "s": info["s_end"],
                "x": float(poses[max(k - 1, 0), 0]), "y": float(poses[max(k - 1, 0), 1]),
                "end_error": info["end_error"], "end_heading_error": info["end_heading_error"],
            }
            break
    return TrainCheckResult(
        ok=failure is None, s=s, poses=poses, headings=headings, x=x, y=y,
        max_abs_phi=max_abs_phi, min_clearance=float(clear.min()), failure=failure,
        collisions=collisions, pulls=pull_info,
    )
