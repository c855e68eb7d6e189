"""Recover the line/arc segments of a Reeds-Shepp path from its interpolation.

OMPL 2.0.1's Python bindings give ``ReedsSheppStateSpace.interpolate`` and ``distance`` but not
the segment types and lengths of the path. A Reeds-Shepp path is at most five *primitives*, each
a left arc (L), a straight line (S) or a right arc (R) of radius ``rho`` travelled forward (+) or
backward (-). This module recovers them from any function ``interp(t) -> (x, y, yaw)``,
t in [0, 1], that evaluates the path at the fraction t of its length (OMPL's interpolation is
evaluated afresh from the start for every t, so it is exact to rounding everywhere).

Method: from the current breakpoint, a short probe step identifies the primitive (the one of the
six whose predicted pose matches the interpolated pose to ``tol``; the probe shrinks until it
lies inside one primitive); then the path is walked on a grid until the prediction fails and
the breakpoint is located by bisection. Every change of primitive changes either the heading or
the position at first order in the distance past the breakpoint (curvature change: heading;
direction change: position), so the comparison of pose *and* heading locates breakpoints to
about ``tol`` metres.

Poses here are in the planner's frame: ``yaw`` is the direction of travel when pushing
(chain heading theta + pi), so forward (+) is pushing and backward (-) is pulling.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

__all__ = ["Primitive", "recover_primitives", "advance_yaw", "evaluate_primitives"]

_TURN = {"L": 1.0, "S": 0.0, "R": -1.0}

MAX_WALK_STEPS = 2000
"""Most grid steps :func:`recover_primitives` walks along one primitive (whatever the radius):
a breakpoint is found by bisection between the last step that matches and the first that does
not, so a coarser walk only costs a few more bisections."""


@dataclass(frozen=True)
class Primitive:
    """One piece of a Reeds-Shepp path.

    Parameters
    ----------
    turn : "L", "S" or "R"
        Left arc, straight line, right arc.
    gear : int
        +1 forward (travel along yaw: pushing), -1 backward (pulling).
    length : float
        Distance travelled [m], > 0.
    """

    turn: str
    gear: int
    length: float


def advance_yaw(x: float, y: float, yaw: float, turn: str, gear: int, dist, rho: float):
    """Pose after travelling ``dist`` [m] (scalar or array) on a primitive of radius ``rho`` [m].

    Same formulas as OMPL's ``ReedsSheppStateSpace::interpolate`` (scaled by rho).
    """
    k = _TURN[turn]
    if isinstance(dist, float):  # one pose: plain floats (the recovery asks thousands)
        v = gear * dist / rho
        if k == 0.0:
            return x + rho * v * math.cos(yaw), y + rho * v * math.sin(yaw), yaw
        phi = yaw + k * v
        return (x + rho * k * (math.sin(phi) - math.sin(yaw)),
                y - rho * k * (math.cos(phi) - math.cos(yaw)), phi)
    dist = np.asarray(dist, dtype=float)
    v = gear * dist / rho  # signed normalized length
    if k == 0.0:
        return x + rho * v * math.cos(yaw), y + rho * v * math.sin(yaw), yaw + 0.0 * v
    phi = yaw + k * v
    return (
        x + rho * k * (np.sin(phi) - math.sin(yaw)),
        y - rho * k * (np.cos(phi) - math.cos(yaw)),
        phi,
    )


def _mismatch(pose0, pose1, turn, gear, dist, rho) -> float:
    """Position error [m] plus rho times the heading error between prediction and ``pose1``."""
    x, y, yaw = advance_yaw(pose0[0], pose0[1], pose0[2], turn, gear, dist, rho)
    dyaw = (float(yaw) - pose1[2] + math.pi) % (2.0 * math.pi) - math.pi
    return math.hypot(float(x) - pose1[0], float(y) - pose1[1]) + rho * abs(dyaw)


def _classify(pose0, pose1, dist, rho, tol):
    """The primitive (turn, gear) that moves ``pose0`` to ``pose1`` over ``dist`` [m], or None."""
    best, best_err = None, math.inf
    for turn in ("S", "L", "R"):
        for gear in (1, -1):
            err = _mismatch(pose0, pose1, turn, gear, dist, rho)
            if err < best_err:
                best, best_err = (turn, gear), err
    return best if best_err <= tol else None


def recover_primitives(
    interp: Callable[[float], tuple[float, float, float]],
    total_length: float,
    rho: float,
    tol: float = 1e-9,
    grid_step: float | None = None,
    max_primitives: int = 12,
) -> list[Primitive]:
    """Primitives of the path ``interp`` of length ``total_length`` [m] and turning radius rho.

    Parameters
    ----------
    interp : callable
        ``t -> (x, y, yaw)`` for t in [0, 1] [m, m, rad].
    total_length : float
        Path length [m] (OMPL: ``distance(a, b)``, which is rho times the normalized length).
    rho : float
        Turning radius [m].
    tol : float
        Pose-match tolerance [m]; breakpoints are located to about this accuracy.
    grid_step : float or None
        Walk step [m]; default rho / 8, but at least ``total_length /`` :data:`MAX_WALK_STEPS`
        (a tiny radius would otherwise walk a path in tens of millions of steps: 8.5 m at
        rho = 1e-6 m, 68 million interpolations, 260 s, none charged to a planning budget).

    Returns
    -------
    list of Primitive
        Adjacent primitives with the same turn and gear are merged; pieces shorter than ``tol``
        are dropped.
    """
    if total_length <= tol:
        return []
    if grid_step is None:
        grid_step = max(rho / 8.0, total_length / MAX_WALK_STEPS)
    step = grid_step / total_length
    out: list[Primitive] = []
    t0, pose0 = 0.0, tuple(map(float, interp(0.0)))
    for _ in range(max_primitives):
        if t0 >= 1.0 - tol / total_length:
            break
        # 1. identify the primitive that starts at t0 with a probe that shrinks until it fits
        # (down to a thousandth of tol: a piece shorter than tol, e.g. OMPL's 1e-8 m reversal at
        # the start of some curves, must be found to be stepped over)
        h = min(step, 1.0 - t0)
        prim = None
        while prim is None and h * total_length > 1e-3 * tol:
            prim = _classify(pose0, tuple(map(float, interp(t0 + h))), h * total_length, rho, tol)
            if prim is None:
                h *= 0.25
        if prim is None:
            raise RuntimeError(
                f"Reeds-Shepp recovery: no primitive matches at t = {t0:.12g} "
                f"(pose {pose0}); the interpolation is not a line/arc path of radius {rho} m"
            )
        turn, gear = prim

        def matches(t, pose0=pose0, turn=turn, gear=gear, t0=t0):
            p1 = tuple(map(float, interp(t)))
            return _mismatch(pose0, p1, turn, gear, (t - t0) * total_length, rho) <= tol

        # 2. walk the grid until the prediction fails, then bisect the breakpoint
        lo, hi = t0 + h, None
        t = lo
        while t < 1.0:
            t = min(t + step, 1.0)
            if matches(t):
                lo = t
            else:
                hi = t
                break
        if hi is None:
            t1 = 1.0
        else:
            for _ in range(200):
                if (hi - lo) * total_length <= 0.05 * tol:
                    break
                mid = 0.5 * (lo + hi)
                if matches(mid):
                    lo = mid
                else:
                    hi = mid
            t1 = lo
        length = (t1 - t0) * total_length
        if length > tol:
            if out and out[-1].turn == turn and out[-1].gear == gear:
                out[-1] = Primitive(turn, gear, out[-1].length + length)
            else:
                out.append(Primitive(turn, gear, length))
        t0, pose0 = t1, tuple(map(float, interp(t1)))
    else:
        raise RuntimeError(
            f"Reeds-Shepp recovery: more than {max_primitives} primitives; stopped at t = {t0}"
        )
    return out


def evaluate_primitives(start, primitives, rho: float, s) -> np.ndarray:
    """Poses (x, y, yaw) [m, m, rad] at travelled distances ``s`` [m] along the primitives.

    Independent of OMPL; used to check the recovery. Shape (len(s), 3); yaw is continuous.
    """
    s = np.atleast_1d(np.asarray(s, dtype=float))
    out = np.empty((s.size, 3))
    pose = tuple(map(float, start))
    s0 = 0.0
    bounds = np.cumsum([p.length for p in primitives])
    for k, prim in enumerate(primitives):
        last = k == len(primitives) - 1
        mask = (s >= s0) & ((s <= bounds[k]) if last else (s < bounds[k]))
        x, y, yaw = advance_yaw(*pose, prim.turn, prim.gear, s[mask] - s0, rho)
        out[mask] = np.column_stack([x, y, yaw])
        x, y, yaw = advance_yaw(*pose, prim.turn, prim.gear, prim.length, rho)
        pose, s0 = (float(x), float(y), float(yaw)), float(bounds[k])
    if primitives:
        out[s > bounds[-1]] = pose
        out[s < 0.0] = tuple(map(float, start))
    else:
        out[:] = tuple(map(float, start))
    return out
