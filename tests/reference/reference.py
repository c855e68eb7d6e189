"""The last trailer's line/arc reference written in Python: the reference the engine's (the phase
table and sampling of ``core/csrc/control.c``, :class:`pushtrain.core.reference.Reference`) is
held equal to, bit for bit (``tests/core/test_native.py``).

One row per phase (a segment, or a dwell at a cusp): start time, start pose, the sign of v,
the curvature and the speed; a sample advances the row's pose in closed form (Eq. 1).
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from pushtrain.core.kinematics import wrap_angle
from pushtrain.core.reference import ReferenceSample
from pushtrain.core.segment import PULL, REST, Segment
from pushtrain.errors import ReferencePathError


def _advance(x, y, theta, sigma, kappa, s, sin=math.sin, cos=math.cos):
    """Pose after travelling ``s`` [m] from ``(x, y, theta)`` along a line or arc (Eq. 1
    integrated in closed form).

    ``sigma`` is the sign of v (-direction, 0 at rest) and ``kappa`` the curvature [1/m]; below
    1e-12 1/m the segment counts as straight. With :func:`math.sin`, :func:`math.cos` for a float
    ``s``, with :func:`numpy.sin`, :func:`numpy.cos` for an array of distances (the same formulas,
    element by element).
    """
    th = theta + kappa * s
    if abs(kappa) < 1e-12:
        return x + sigma * s * cos(theta), y + sigma * s * sin(theta), th
    return (
        x + sigma * (sin(th) - sin(theta)) / kappa,
        y - sigma * (cos(th) - cos(theta)) / kappa,
        th,
    )


@dataclass
class Reference:
    """Piecewise line/arc reference of the last trailer, evaluated analytically at any time.

    Build it with :meth:`from_segments`. Times are seconds from ``t0``.
    """

    start: tuple[float, float, float]
    segments: tuple[Segment, ...]
    speed: float = 0.1
    cusp_dwell: float = 1.0
    t0: float = 0.0
    # Derived tables (one row per phase: a segment or a dwell at a cusp).
    _t_start: np.ndarray = field(init=False, repr=False)
    _pose0: np.ndarray = field(init=False, repr=False)
    _sigma: np.ndarray = field(init=False, repr=False)  # sign of v: -direction, 0 at rest
    _kappa: np.ndarray = field(init=False, repr=False)
    _speed: np.ndarray = field(init=False, repr=False)
    _t_end: float = field(init=False, repr=False)
    _rows: tuple = field(init=False, repr=False)  # plain-float copy of the tables for sample_at

    @classmethod
    def from_segments(
        cls,
        start: Sequence[float],
        segments: Sequence[Segment],
        speed: float = 0.1,
        cusp_dwell: float = 1.0,
        t0: float = 0.0,
    ) -> Reference:
        """Reference starting at ``start = (x, y, theta)`` [m, m, rad] through ``segments``.

        ``speed`` [m/s] applies to segments without their own; ``cusp_dwell`` [s] is the rest at
        every direction change.
        """
        return cls(tuple(float(a) for a in start), tuple(segments), speed, cusp_dwell, t0)

    def __post_init__(self):
        if len(self.start) != 3 or not np.all(np.isfinite(self.start)):
            raise ReferencePathError(
                f"start = {self.start!r}: need three finite numbers (x, y, theta)"
            )
        if not self.segments:
            raise ReferencePathError("a reference needs at least one segment")
        if not (np.isfinite(self.speed) and self.speed > 0.0):
            raise ReferencePathError(f"speed = {self.speed!r} m/s: must be finite and > 0")
        if not (np.isfinite(self.cusp_dwell) and self.cusp_dwell >= 0.0):
            raise ReferencePathError(f"cusp_dwell = {self.cusp_dwell!r} s: must be finite and >= 0")
        t, pose = self.t0, np.array(self.start, dtype=float)
        rows_t, rows_pose, rows_sigma, rows_kappa, rows_speed = [], [], [], [], []
        previous_direction = None
        for seg in self.segments:
            if not isinstance(seg, Segment):
                raise ReferencePathError(
                    f"segments must be Segment objects, got {type(seg).__name__}"
                )
            if previous_direction is not None and seg.direction != previous_direction:
                if self.cusp_dwell > 0.0:
                    rows_t.append(t), rows_pose.append(pose.copy())
                    rows_sigma.append(0.0), rows_kappa.append(0.0), rows_speed.append(0.0)
                    t += self.cusp_dwell
            speed = self.speed if seg.speed is None else seg.speed
            rows_t.append(t), rows_pose.append(pose.copy())
            rows_sigma.append(-float(seg.direction)), rows_kappa.append(float(seg.curvature))
            rows_speed.append(speed)
            pose = np.array(_advance(*(float(a) for a in pose), -float(seg.direction),
                                     float(seg.curvature), float(seg.length)))
            t += seg.length / speed
            previous_direction = seg.direction
        self._t_start = np.array(rows_t)
        self._pose0 = np.array(rows_pose)
        self._sigma = np.array(rows_sigma)
        self._kappa = np.array(rows_kappa)
        self._speed = np.array(rows_speed)
        self._t_end = t
        self._rows = (
            [float(a) for a in self._t_start],
            tuple(
                (float(p[0]), float(p[1]), float(p[2]), float(sg), float(kp), float(sp))
                for p, sg, kp, sp in zip(self._pose0, self._sigma, self._kappa, self._speed,
                                         strict=True)
            ),
        )

    @property
    def t_end(self) -> float:
        """Time [s] at which the reference reaches its goal and stops."""
        return self._t_end

    @property
    def goal(self) -> np.ndarray:
        """Final pose (x, y, theta) [m, m, rad], theta wrapped to (-pi, pi]."""
        x, y, th, _, _ = self.sample(np.array([self._t_end]))
        return np.array([x[0], y[0], wrap_angle(th[0])])

    @property
    def length(self) -> float:
        """Total travelled distance [m]."""
        return float(sum(seg.length for seg in self.segments))

    def sample(self, t):
        """Reference at times ``t`` [s] (array): ``(x, y, theta, v, w)``.

        ``theta`` is continuous (not wrapped). Before ``t0`` the reference rests at the start,
        after :attr:`t_end` at the goal with v = w = 0.
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        tc = np.clip(t, self.t0, self._t_end)
        k = np.clip(np.searchsorted(self._t_start, tc, side="right") - 1, 0, len(self._t_start) - 1)
        x, y, th = (np.empty_like(tc) for _ in range(3))
        for row in np.unique(k):
            at = k == row
            x0, y0, th0, sigma, kappa, speed = self._rows[1][row]
            s = speed * (tc[at] - self._t_start[row])
            x[at], y[at], th[at] = _advance(x0, y0, th0, sigma, kappa, s, np.sin, np.cos)
        moving = (t >= self.t0) & (t < self._t_end)
        v = np.where(moving, self._sigma[k] * self._speed[k], 0.0)
        w = np.where(moving, self._kappa[k] * self._speed[k], 0.0)
        return x, y, th, v, w

    def direction_at(self, t) -> np.ndarray:
        """Direction at times ``t``: +1 push, -1 pull, 0 at rest (dwell, before start, after goal).
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        k = np.clip(np.searchsorted(self._t_start, t, side="right") - 1, 0, len(self._t_start) - 1)
        moving = (t >= self.t0) & (t < self._t_end)
        return np.where(moving, -self._sigma[k], 0.0).astype(int)

    def pull_intervals(self) -> list[tuple[float, float]]:
        """Start and end times [s] of every maximal pulling run (consecutive pulling segments)."""
        return _pull_intervals(np.append(self._t_start, self._t_end), -self._sigma)

    def sample_at(self, t: float) -> ReferenceSample:
        """Reference at one time ``t`` [s] as plain floats (fast scalar form of :meth:`sample`).

        Returns
        -------
        ReferenceSample
            Pose, velocities and direction (:data:`REST` during a cusp dwell, before ``t0`` and
            from :attr:`t_end` on, where v = w = 0).
        """
        t = float(t)
        t_start, rows = self._rows
        tc = min(max(t, self.t0), self._t_end)
        k = min(max(bisect_right(t_start, tc) - 1, 0), len(rows) - 1)
        x0, y0, th0, sigma, kappa, speed = rows[k]
        x, y, th = _advance(x0, y0, th0, sigma, kappa, speed * (tc - t_start[k]))
        if self.t0 <= t < self._t_end and sigma != 0.0:
            return ReferenceSample(x, y, th, sigma * speed, kappa * speed, int(-sigma))
        return ReferenceSample(x, y, th, 0.0, 0.0, REST)


def _pull_intervals(bounds, directions) -> list[tuple[float, float]]:
    """Maximal intervals [bounds[i], bounds[j]] [s] over consecutive phases i..j-1 whose
    direction is PULL; phase k lasts from ``bounds[k]`` to ``bounds[k + 1]``."""
    pulling = np.asarray(directions) == PULL
    edges = np.diff(np.concatenate(([0], pulling.astype(int), [0])))
    return [(float(bounds[i]), float(bounds[j]))
            for i, j in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True)
            if bounds[j] > bounds[i]]


