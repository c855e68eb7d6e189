"""A reference of the last trailer given as samples (e.g. from a planner or a recorded run),
linearly interpolated, with the query methods of :class:`~pushtrain.core.reference.Reference`.

Conventions are the chain's (see :mod:`pushtrain.core.reference`): ``theta`` toward the robot,
``v`` < 0 when pushing, ``w = d(theta)/dt``.
"""

from __future__ import annotations

from bisect import bisect_right

import numpy as np

from pushtrain.errors import ReferencePathError

from .kinematics import wrap_angle
from .reference import Reference, ReferenceSample
from .segment import PULL, PUSH, REST

__all__ = ["SampledReference"]


def _pull_intervals(bounds, directions) -> list[tuple[float, float]]:
    """Maximal intervals [bounds[i], bounds[j]] [s] over consecutive phases i..j-1 whose
    direction is PULL; phase k lasts from ``bounds[k]`` to ``bounds[k + 1]``."""
    pulling = np.asarray(directions) == PULL
    edges = np.diff(np.concatenate(([0], pulling.astype(int), [0])))
    return [(float(bounds[i]), float(bounds[j]))
            for i, j in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True)
            if bounds[j] > bounds[i]]


def _check_no_jumps(what: str, unit: str, rates: str, change, rate, t, dt, rel_tol, abs_tol):
    """Raise if a sampled ``change`` between neighbours exceeds what the larger of the two
    neighbouring ``rate`` samples allows over ``dt`` (plus tolerances)."""
    allowed = np.maximum(np.abs(rate[:-1]), np.abs(rate[1:])) * dt * (1.0 + rel_tol) + abs_tol
    bad = np.flatnonzero(change > allowed)
    if bad.size:
        k = int(bad[0])
        raise ReferencePathError(
            f"{what} jumps by {change[k]:.6g} {unit} between t = {t[k]!r} s and {t[k + 1]!r} s;"
            f" at most {allowed[k]:.6g} {unit} is allowed by the sampled {rates}"
        )


class SampledReference:
    """Reference of the last trailer given as samples (e.g. from a planner), linearly interpolated.

    The samples must describe a continuous motion: between consecutive samples the position may
    move at most ``max(|v_k|, |v_k+1|) dt (1 + rel_tol) + pos_tol`` and the (unwrapped) heading at
    most ``max(|w_k|, |w_k+1|) dt (1 + rel_tol) + angle_tol``; anything more is a jump and raises
    :class:`ReferencePathError`. The sign of ``v`` must agree with ``direction`` (v <= 0 when
    pushing, >= 0 when pulling, 0 at rest, within ``speed_tol``). The same query methods as
    :class:`Reference` are offered (:meth:`sample`, :meth:`sample_at`,
    :meth:`direction_at`, :attr:`t_end`, :attr:`goal`, :attr:`length`).

    Parameters
    ----------
    t : array of shape (m,)
        Strictly increasing sample times [s], m >= 2.
    x, y : arrays of shape (m,)
        Axle-midpoint positions [m].
    theta : array of shape (m,)
        Headings [rad]; wrapped values are unwrapped first.
    v, w : arrays of shape (m,)
        Signed longitudinal speed [m/s] and yaw rate [rad/s].
    direction : array of shape (m,)
        :data:`PUSH`, :data:`PULL` or :data:`REST`; held from a sample to the next one.
    pos_tol : float
        Absolute position allowance per step [m] (default 1 mm).
    angle_tol : float
        Absolute heading allowance per step [rad] (default 1 mrad).
    rel_tol : float
        Relative allowance on the speed bounds (default 0.05).
    speed_tol : float
        Tolerance of the sign check of ``v`` against ``direction`` [m/s] (default 1e-9).
    """

    def __init__(
        self,
        t,
        x,
        y,
        theta,
        v,
        w,
        direction,
        pos_tol: float = 1e-3,
        angle_tol: float = 1e-3,
        rel_tol: float = 0.05,
        speed_tol: float = 1e-9,
    ):
        names = ("t", "x", "y", "theta", "v", "w", "direction")
        arrays = [np.asarray(a, dtype=float).reshape(-1) for a in (t, x, y, theta, v, w, direction)]
        m = arrays[0].size
        if m < 2:
            raise ReferencePathError(f"a sampled reference needs at least 2 samples, got {m}")
        for name, a in zip(names, arrays, strict=True):
            if a.size != m:
                raise ReferencePathError(
                    f"{name} has {a.size} samples, t has {m}: sizes must agree"
                )
            bad = np.flatnonzero(~np.isfinite(a))
            if bad.size:
                raise ReferencePathError(
                    f"{name}[{bad[0]}] = {a[bad[0]]!r}: samples must be finite"
                )
        for name, value in (
            ("pos_tol", pos_tol),
            ("angle_tol", angle_tol),
            ("rel_tol", rel_tol),
            ("speed_tol", speed_tol),
        ):
            if not (np.isfinite(value) and value >= 0.0):
                raise ReferencePathError(f"{name} = {value!r}: must be finite and >= 0")
        t, x, y, theta, v, w, direction = arrays
        dt = np.diff(t)
        bad = np.flatnonzero(dt <= 0.0)
        if bad.size:
            k = int(bad[0])
            raise ReferencePathError(
                f"t[{k + 1}] = {t[k + 1]!r} s <= t[{k}] = {t[k]!r} s: times must strictly increase"
            )
        bad = np.flatnonzero(~np.isin(direction, (PUSH, PULL, REST)))
        if bad.size:
            k = int(bad[0])
            raise ReferencePathError(
                f"direction[{k}] = {direction[k]!r}: allowed are +1 (push), -1 (pull), 0 (rest)"
            )
        wrong_sign = (
            ((direction == PUSH) & (v > speed_tol))
            | ((direction == PULL) & (v < -speed_tol))
            | ((direction == REST) & (np.abs(v) > speed_tol))
        )
        bad = np.flatnonzero(wrong_sign)
        if bad.size:
            k = int(bad[0])
            raise ReferencePathError(
                f"v[{k}] = {v[k]!r} m/s at t = {t[k]!r} s contradicts direction"
                f" {int(direction[k])}: pushing needs v <= 0, pulling v >= 0, rest v = 0"
            )
        theta = np.unwrap(theta)
        step = np.hypot(np.diff(x), np.diff(y))
        _check_no_jumps("position", "m", "speeds", step, v, t, dt, rel_tol, pos_tol)
        _check_no_jumps("heading", "rad", "yaw rates", np.abs(np.diff(theta)), w, t, dt,
                        rel_tol, angle_tol)
        self._t, self._x, self._y, self._theta = t, x, y, theta
        self._v, self._w, self._direction = v, w, direction.astype(int)
        self._s = np.concatenate(([0.0], np.cumsum(step)))  # distance travelled [m]
        self._t_list = t.tolist()
        self._cols = (
            x.tolist(),
            y.tolist(),
            theta.tolist(),
            v.tolist(),
            w.tolist(),
            self._direction.tolist(),
        )

    @classmethod
    def from_reference(cls, reference: Reference, dt: float, **tolerances) -> SampledReference:
        """Sample a :class:`Reference` every ``dt`` [s] from its ``t0`` to its :attr:`t_end`."""
        if not (np.isfinite(dt) and dt > 0.0):
            raise ReferencePathError(f"dt = {dt!r} s: must be finite and > 0")
        m = int(np.ceil((reference.t_end - reference.t0) / dt)) + 1
        t = reference.t0 + dt * np.arange(m)
        x, y, theta, v, w = reference.sample(t)
        direction = reference.direction_at(t)
        return cls(t, x, y, theta, v, w, direction, **tolerances)

    @property
    def start(self) -> tuple[float, float, float]:
        """First pose (x, y, theta) [m, m, rad]."""
        return (float(self._x[0]), float(self._y[0]), float(self._theta[0]))

    @property
    def t0(self) -> float:
        """Time of the first sample [s]."""
        return self._t_list[0]

    @property
    def t_end(self) -> float:
        """Time of the last sample [s]; the reference rests there afterwards."""
        return self._t_list[-1]

    @property
    def goal(self) -> np.ndarray:
        """Final pose (x, y, theta) [m, m, rad], theta wrapped to (-pi, pi]."""
        return np.array([self._x[-1], self._y[-1], wrap_angle(self._theta[-1])])

    @property
    def length(self) -> float:
        """Total travelled distance [m] (sum of the sample-to-sample distances)."""
        return float(self._s[-1])

    def sample(self, t):
        """Reference at times ``t`` [s] (array): ``(x, y, theta, v, w)``, linearly interpolated.

        Outside the sampled span the reference rests at its first or last pose with v = w = 0.
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        inside = (t >= self._t[0]) & (t < self._t[-1])
        out = [np.interp(t, self._t, col) for col in (self._x, self._y, self._theta)]
        out += [np.where(inside, np.interp(t, self._t, col), 0.0) for col in (self._v, self._w)]
        return tuple(out)

    def direction_at(self, t) -> np.ndarray:
        """Direction held from the preceding sample; :data:`REST` outside the sampled span."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        k = np.clip(np.searchsorted(self._t, t, side="right") - 1, 0, self._t.size - 1)
        inside = (t >= self._t[0]) & (t < self._t[-1])
        return np.where(inside, self._direction[k], REST).astype(int)

    def pull_intervals(self) -> list[tuple[float, float]]:
        """Start and end times [s] of every maximal run of pulling samples (a sample's direction
        holds until the next sample)."""
        return _pull_intervals(self._t, self._direction[:-1])

    def sample_at(self, t: float) -> ReferenceSample:
        """Reference at one time ``t`` [s] as plain floats: :meth:`sample` and
        :meth:`direction_at` at one time, equal to them bit for bit (the interpolation of
        :func:`numpy.interp`: ``slope * (t - t_k) + value_k``, a sample's own value at its time)."""
        t = float(t)
        ts = self._t_list
        tc = min(max(t, ts[0]), ts[-1])
        k = bisect_right(ts, tc) - 1
        if k == len(ts) - 1 or ts[k] == tc:
            values = [col[k] for col in self._cols[:5]]
        else:
            dt, dtc = ts[k + 1] - ts[k], tc - ts[k]
            values = [(col[k + 1] - col[k]) / dt * dtc + col[k] for col in self._cols[:5]]
        if ts[0] <= t < ts[-1]:
            return ReferenceSample(*values, int(self._cols[5][k]))
        return ReferenceSample(*values[:3], 0.0, 0.0, REST)
