"""Reeds-Shepp curves of OMPL between planner states, and their line/arc segments.

Planner state: the last trailer's axle midpoint (x, y) and ``yaw`` = its direction of travel
when pushing, yaw = theta + pi (theta: chain heading, toward the robot). Reeds-Shepp "forward"
is therefore pushing (:data:`~pushtrain.core.reference.PUSH`, trailer leads) and "backward"
pulling (:data:`~pushtrain.core.reference.PULL`, robot leads).

OMPL's camelCase stays in the planner's modules that import ompl (this one and
:mod:`~pushtrain.planner.ompl_search`); results are converted to numpy at once.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from ompl import base as ob

from pushtrain.core.reference import PULL, PUSH, Segment

from .reeds_shepp import Primitive, evaluate_primitives, recover_primitives

__all__ = ["ReedsSheppCurve", "rs_distance", "primitives_to_segments", "reeds_shepp_space",
           "chain_to_planner_state", "segments_from_states", "sample_curve_into",
           "travel_between_states", "wrap_yaw"]


def reeds_shepp_space(rho: float, bounds) -> ob.ReedsSheppStateSpace:
    """OMPL's Reeds-Shepp space of radius ``rho`` [m] on ``bounds`` (xmin, ymin, xmax, ymax)."""
    space = ob.ReedsSheppStateSpace(float(rho))
    b = ob.RealVectorBounds(2)
    b.setLow(0, bounds[0])
    b.setLow(1, bounds[1])
    b.setHigh(0, bounds[2])
    b.setHigh(1, bounds[3])
    space.setBounds(b)
    return space


def wrap_yaw(yaw: float) -> float:
    """Yaw in [-pi, pi) as OMPL's SO2 bounds require."""
    return (float(yaw) + math.pi) % (2.0 * math.pi) - math.pi


class ReedsSheppCurve:
    """OMPL's Reeds-Shepp curve between two planner states (x, y, yaw) for radius ``rho``.

    ``length`` is OMPL's ``distance`` [m]; :meth:`interpolate` is OMPL's ``interpolate`` at
    the fraction t in [0, 1]; :meth:`primitives` recovers the line/arc pieces.
    """

    def __init__(self, rho: float, a: Sequence[float], b: Sequence[float]):
        pad = 2.0 * rho + 1.0
        lo = min(a[0], b[0]) - pad, min(a[1], b[1]) - pad
        hi = max(a[0], b[0]) + pad, max(a[1], b[1]) + pad
        self.rho = float(rho)
        self._space = reeds_shepp_space(rho, (lo[0], lo[1], hi[0], hi[1]))
        self._a, self._b, self._out = (self._space.allocState() for _ in range(3))
        for state, pose in ((self._a, a), (self._b, b)):
            state.setX(float(pose[0]))
            state.setY(float(pose[1]))
            state.setYaw(wrap_yaw(pose[2]))
        self.length = float(self._space.distance(self._a, self._b))

    def interpolate(self, t: float) -> tuple[float, float, float]:
        """Pose (x, y, yaw) at the fraction ``t`` of the curve."""
        self._space.interpolate(self._a, self._b, float(t), self._out)
        return self._out.getX(), self._out.getY(), self._out.getYaw()

    def primitives(self, tol: float = 1e-9) -> list[Primitive]:
        """Recovered line/arc pieces (see :mod:`pushtrain.planner.reeds_shepp`)."""
        return recover_primitives(self.interpolate, self.length, self.rho, tol)


def rs_distance(rho: float, a: Sequence[float], b: Sequence[float]) -> float:
    """Length [m] of the shortest Reeds-Shepp curve from pose ``a`` to ``b`` (x, y, yaw)."""
    return ReedsSheppCurve(rho, a, b).length


def primitives_to_segments(primitives: Sequence[Primitive], rho: float) -> list[Segment]:
    """Planner-frame primitives -> reference segments (forward = PUSH, backward = PULL).

    The chain heading theta = yaw + pi changes like yaw, so d(theta)/ds per metre travelled is
    +1/rho for a left arc driven forward, -1/rho backward, and the opposite for right arcs.
    """
    out = []
    for p in primitives:
        direction = PUSH if p.gear > 0 else PULL
        if p.turn == "S":
            out.append(Segment("line", p.length, 0.0, direction))
        else:
            k = (1.0 if p.turn == "L" else -1.0) * p.gear / rho
            out.append(Segment("arc", p.length, k, direction))
    return out


def _merge(segments: Sequence[Segment]) -> list[Segment]:
    out: list[Segment] = []
    for g in segments:
        if out and (out[-1].kind, out[-1].curvature, out[-1].direction) == (
            g.kind, g.curvature, g.direction
        ):
            out[-1] = Segment(g.kind, out[-1].length + g.length, g.curvature, g.direction)
        else:
            out.append(g)
    return out


def sample_curve_into(rows: list, space, a, b, m: int, tmp) -> None:
    """Append to ``rows`` the states (x, y, yaw) of OMPL's curve ``a -> b`` at the fractions
    k/m, k = 1..m (``tmp``: a scratch state of ``space``)."""
    interpolate, get_x, get_y, get_yaw = space.interpolate, tmp.getX, tmp.getY, tmp.getYaw
    for k in range(1, m + 1):
        interpolate(a, b, k / m, tmp)
        rows.append((get_x(), get_y(), get_yaw()))


def travel_between_states(pts: np.ndarray):
    """Travel between consecutive planner states ``pts`` (K, 3) = (x, y, yaw): whether each step
    k -> k+1 goes backward (against the yaw at its middle), its yaw change [rad] and its
    length [m], each (K-1,)."""
    dyaw = (np.diff(pts[:, 2]) + math.pi) % (2.0 * math.pi) - math.pi
    mid = pts[:-1, 2] + 0.5 * dyaw
    d = np.diff(pts[:, :2], axis=0)
    backward = d[:, 0] * np.cos(mid) + d[:, 1] * np.sin(mid) < 0.0
    return backward, dyaw, np.hypot(d[:, 0], d[:, 1])


def segments_from_states(states: np.ndarray, rho: float) -> tuple[list[Segment], float]:
    """Line/arc segments of the Reeds-Shepp path through ``states`` (planner frame), and the
    largest deviation [m] between the segments and OMPL's interpolation (checked at 33 points
    per local curve)."""
    prims: list[Primitive] = []
    worst = 0.0
    for a, b in zip(states[:-1], states[1:], strict=True):
        curve = ReedsSheppCurve(rho, a, b)
        p = curve.primitives()
        if curve.length > 0.0 and p:
            ts = np.linspace(0.0, 1.0, 33)
            ref = np.array([curve.interpolate(t) for t in ts])
            ev = evaluate_primitives(a, p, rho, ts * curve.length)
            worst = max(worst, float(np.hypot(*(ev[:, :2] - ref[:, :2]).T).max()))
        prims += p
    return _merge(primitives_to_segments(prims, rho)), worst


def chain_to_planner_state(pose) -> tuple[float, float, float]:
    """Chain pose (x, y, theta) -> planner state (x, y, yaw = theta + pi)."""
    return float(pose[0]), float(pose[1]), float(pose[2]) + math.pi
