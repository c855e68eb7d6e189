"""Time-parameterized reference for the last trailer (Step 1 of the paper).

The reference is the contract between :mod:`pushtrain.planner` (which fills it from a Reeds-Shepp
path) and the co-simulation master (which samples it every communication step).

Conventions are the chain's (see :mod:`pushtrain.core.kinematics`): ``theta`` is the last
trailer's heading pointing toward the robot, ``v`` its signed longitudinal speed (negative when
pushing: the trailer leads), ``w = d(theta)/dt``. Eq. (1) of the paper in this +x convention::

    dx/dt = v cos(theta),  dy/dt = v sin(theta),  d(theta)/dt = w

A :class:`Segment` is a line or an arc travelled at constant speed in one direction. Its
``curvature`` is d(theta)/ds per metre *travelled* (s increases in both directions), so
``w = curvature * |v|``. Direction changes (cusps) are stops: the reference rests for
``cusp_dwell`` seconds and continues the other way.
"""

from __future__ import annotations

import ctypes
import math
from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal, NamedTuple

import numpy as np

from pushtrain.defaults import CUSP_DWELL, REFERENCE_SPEED
from pushtrain.errors import ReferencePathError

from . import native
from .kinematics import wrap_angle

__all__ = ["PULL", "PUSH", "REST", "Reference", "ReferenceSample", "SampledReference", "Segment",
           "path_points", "segment_struct"]

PUSH = +1
"""Direction of a segment travelled trailer first (the robot pushes): v < 0."""
PULL = -1
"""Direction of a segment travelled robot first (the robot pulls): v > 0."""


REST = 0
"""Direction value while the reference rests (cusp dwell, before the start, after the goal)."""


class ReferenceSample(NamedTuple):
    """The last trailer's reference at one time (chain conventions, see the module docstring).

    Attributes
    ----------
    x, y : float
        Axle-midpoint position [m].
    theta : float
        Heading [rad], pointing toward the robot, continuous (not wrapped).
    v : float
        Signed longitudinal speed [m/s]: < 0 when pushing, > 0 when pulling, 0 at rest.
    w : float
        Yaw rate d(theta)/dt [rad/s].
    direction : int
        :data:`PUSH` (+1), :data:`PULL` (-1) or :data:`REST` (0).
    """

    x: float
    y: float
    theta: float
    v: float
    w: float
    direction: int


@dataclass(frozen=True)
class Segment:
    """One line or arc of the last trailer's path.

    Parameters
    ----------
    kind : "line" or "arc"
    length : float
        Distance travelled along the segment [m], > 0.
    curvature : float
        d(theta)/ds [1/m] per metre travelled; 0 for a line, CCW positive.
    direction : int
        :data:`PUSH` (+1, trailer leads, v < 0) or :data:`PULL` (-1, robot leads, v > 0).
    speed : float or None
        Travel speed |v| [m/s]; ``None`` takes the reference's default speed.
    """

    kind: Literal["line", "arc"]
    length: float
    curvature: float = 0.0
    direction: int = PUSH
    speed: float | None = None

    def __post_init__(self):
        if self.kind not in ("line", "arc"):
            raise ReferencePathError(f"segment kind = {self.kind!r}: allowed are 'line' and 'arc'")
        if not (np.isfinite(self.length) and self.length > 0.0):
            raise ReferencePathError(f"segment length = {self.length!r} m: must be finite and > 0")
        if not np.isfinite(self.curvature):
            raise ReferencePathError(f"segment curvature = {self.curvature!r} 1/m: must be finite")
        if self.kind == "line" and self.curvature != 0.0:
            raise ReferencePathError(f"a line has curvature 0, got {self.curvature!r} 1/m")
        if self.kind == "arc" and self.curvature == 0.0:
            raise ReferencePathError("an arc needs a non-zero curvature")
        if self.direction not in (PUSH, PULL):
            raise ReferencePathError(
                f"segment direction = {self.direction!r}: allowed are +1 (push) and -1 (pull)"
            )
        if self.speed is not None and not (np.isfinite(self.speed) and self.speed > 0.0):
            raise ReferencePathError(f"segment speed = {self.speed!r} m/s: must be finite and > 0")

    @classmethod
    def from_dict(cls, data: dict) -> Segment:
        """The segment of its plain form (``path.json``, a planning failure's ``closest``):
        ``kind``, ``length``, ``curvature``, ``direction`` ('push' or 'pull'), ``speed``."""
        direction = {"push": PUSH, "pull": PULL}.get(data.get("direction"))
        if direction is None:
            raise ReferencePathError(f"segment direction = {data.get('direction')!r}: allowed "
                                     "are 'push' and 'pull'")
        return cls(data["kind"], float(data["length"]), float(data.get("curvature", 0.0)),
                   direction, data.get("speed"))


def path_points(start, segments, spacing: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """Positions (x, y) [m] every ``spacing`` metres along ``segments`` from ``start``
    (x, y, theta), both ends included."""
    ref = Reference.from_segments(tuple(start[:3]), list(segments), speed=1.0, cusp_dwell=0.0)
    s = np.linspace(0.0, ref.t_end, max(2, int(ref.t_end / spacing) + 1))
    x, y, _, _, _ = ref.sample(s)
    return np.asarray(x), np.asarray(y)


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


_KINDS = {"line": 0, "arc": 1}


def segment_struct(segment: Segment):
    """The C ``PtSegment`` of a :class:`Segment` (speed 0: the reference's default)."""
    if not isinstance(segment, Segment):
        raise ReferencePathError(f"segments must be Segment objects, got "
                                 f"{type(segment).__name__}")
    return native.PtSegment(float(segment.length), float(segment.curvature),
                            0.0 if segment.speed is None else float(segment.speed),
                            int(segment.direction), _KINDS[segment.kind])


class Reference:
    """Piecewise line/arc reference of the last trailer, evaluated analytically at any time.

    The one reference of the product: its phase table (one row per phase, a segment or a dwell
    at a cusp) and its sampling are the engine's (``pt_reference_init``, ``_append``,
    ``_sample`` in ``core/csrc/control.c``), which the co-simulation master, the planner's
    rollouts and the controller FMU read as they are; this class is their Python face. It can
    grow segment by segment (:meth:`append`, :meth:`copy`, :meth:`continuation`: a planner
    extends the reference so far). Build a whole one with :meth:`from_segments`. Times are
    seconds from ``t0``.

    Parameters
    ----------
    start : (x, y, theta)
        Start pose [m, m, rad] at ``t0``.
    segments : sequence of Segment
        Appended at once (more can follow with :meth:`append`).
    speed : float
        Default |v| [m/s] of segments without their own, > 0 (default the scenario's,
        :data:`pushtrain.defaults.REFERENCE_SPEED`, 0.08 m/s).
    cusp_dwell : float
        Rest [s] at every direction change, >= 0.
    t0 : float
        Start time [s].
    previous_direction : int
        Direction of the motion before ``t0`` (0: none). A first segment of the other
        direction starts with a dwell, as inside one longer reference.
    """

    def __init__(self, start: Sequence[float], segments: Sequence[Segment] = (),
                 speed: float = REFERENCE_SPEED, cusp_dwell: float = CUSP_DWELL, t0: float = 0.0,
                 previous_direction: int = 0):
        if len(start) != 3 or not np.all(np.isfinite(np.asarray(start, dtype=float))):
            raise ReferencePathError(
                f"start = {start!r}: need three finite numbers (x, y, theta)"
            )
        if not (np.isfinite(speed) and speed > 0.0):
            raise ReferencePathError(f"speed = {speed!r} m/s: must be finite and > 0")
        if not (np.isfinite(cusp_dwell) and cusp_dwell >= 0.0):
            raise ReferencePathError(f"cusp_dwell = {cusp_dwell!r} s: must be finite and >= 0")
        self._lib = native.load()
        self._table = np.zeros((max(8, 2 * len(segments) + 2), 7))
        self.struct = native.PtReference()
        """The C ``PtReference`` (the phase table behind it stays alive with this object)."""
        start_arr = np.array([float(a) for a in start], dtype=float)
        status = self._lib.pt_reference_init(
            ctypes.byref(self.struct), self._phases_ptr(), self._table.shape[0],
            native.dptr(start_arr), float(speed), float(cusp_dwell), float(t0),
            int(previous_direction))
        if status:
            raise ReferencePathError(
                f"reference t0 = {t0!r} s, previous_direction = {previous_direction!r}: need a "
                "finite t0 and a direction of +1, -1 or 0")
        self.start = tuple(float(a) for a in start_arr)
        self._previous = int(previous_direction)
        self._segments: list[Segment] = []
        self._sample = native.PtSample()
        self.extend(segments)

    @classmethod
    def from_segments(
        cls,
        start: Sequence[float],
        segments: Sequence[Segment],
        speed: float = REFERENCE_SPEED,
        cusp_dwell: float = CUSP_DWELL,
        t0: float = 0.0,
    ) -> Reference:
        """Reference starting at ``start = (x, y, theta)`` [m, m, rad] through ``segments``
        (at least one).

        ``speed`` [m/s] applies to segments without their own; ``cusp_dwell`` [s] is the rest at
        every direction change.
        """
        if not segments:
            raise ReferencePathError("a reference needs at least one segment")
        return cls(tuple(float(a) for a in start), tuple(segments), speed, cusp_dwell, t0)

    def __reduce__(self):
        return (_rebuild, (self.start, tuple(self._segments), self.speed, self.cusp_dwell,
                           self.t0, self._previous))

    def __repr__(self) -> str:
        return (f"Reference(start={self.start!r}, segments={self.segments!r}, "
                f"speed={self.speed!r}, cusp_dwell={self.cusp_dwell!r}, t0={self.t0!r})")

    def _phases_ptr(self):
        return self._table.ctypes.data_as(ctypes.POINTER(native.PtPhase))

    # ------------------------------------------------------------------ growing
    def append(self, segment: Segment) -> None:
        """Append one segment (its dwell first if it changes direction)."""
        seg = segment_struct(segment)
        if self.struct.n_phases + 2 > self.struct.capacity:
            table = np.zeros((2 * self._table.shape[0], 7))
            table[: self.struct.n_phases] = self._table[: self.struct.n_phases]
            self._table = table
            self.struct.phases = self._phases_ptr()
            self.struct.capacity = table.shape[0]
        status = self._lib.pt_reference_append(ctypes.byref(self.struct), ctypes.byref(seg))
        if status:
            raise ReferencePathError(f"segment {segment!r} refused by the reference: "
                                     f"{native.STATUS.get(status, status)}")
        self._segments.append(segment)

    def extend(self, segments: Sequence[Segment]) -> None:
        """Append segments in order."""
        for segment in segments:
            self.append(segment)

    def copy(self) -> Reference:
        """An independent copy (for branching: extend the copy, keep this one)."""
        other = Reference.__new__(Reference)
        other._lib = self._lib
        other._table = self._table.copy()
        other.struct = native.PtReference()
        ctypes.memmove(ctypes.byref(other.struct), ctypes.byref(self.struct),
                       ctypes.sizeof(native.PtReference))
        other.struct.phases = other._phases_ptr()
        other.start, other._previous = self.start, self._previous
        other._segments = list(self._segments)
        other._sample = native.PtSample()
        return other

    def continuation(self, segments: Sequence[Segment] = ()) -> Reference:
        """A new reference that starts where this one ends (pose, time :attr:`t_end`, last
        direction) with ``segments``: sampled at or after :attr:`t_end` it equals this
        reference extended by the same segments, bit for bit."""
        s = self.struct
        return Reference((s.x_end, s.y_end, s.theta_end), segments, s.speed, s.cusp_dwell,
                         s.t_end, s.last_direction)

    # ------------------------------------------------------------------ queries
    @property
    def segments(self) -> tuple[Segment, ...]:
        """The segments in order."""
        return tuple(self._segments)

    @property
    def t0(self) -> float:
        """Start time [s]."""
        return float(self.struct.t0)

    @property
    def speed(self) -> float:
        """Default |v| [m/s]."""
        return float(self.struct.speed)

    @property
    def cusp_dwell(self) -> float:
        """Rest at direction changes [s]."""
        return float(self.struct.cusp_dwell)

    @property
    def t_end(self) -> float:
        """Time [s] at which the reference reaches its goal and stops."""
        return float(self.struct.t_end)

    @property
    def end_pose(self) -> tuple[float, float, float]:
        """Pose (x, y, theta) [m, m, rad] at :attr:`t_end` as the table advances it, theta
        continuous (the start of a :meth:`continuation`)."""
        s = self.struct
        return float(s.x_end), float(s.y_end), float(s.theta_end)

    @property
    def last_direction(self) -> int:
        """Direction of the last segment (the ``previous_direction`` if none was appended)."""
        return int(self.struct.last_direction)

    @property
    def phases(self) -> np.ndarray:
        """The phase table (rows: t, x, y, theta, sigma, kappa, speed), a copy."""
        return self._table[: self.struct.n_phases].copy()

    @property
    def goal(self) -> np.ndarray:
        """Final pose (x, y, theta) [m, m, rad], the sample at :attr:`t_end`, theta wrapped to
        (-pi, pi]."""
        s = self.sample_at(self.t_end)
        return np.array([s.x, s.y, wrap_angle(s.theta)])

    @property
    def length(self) -> float:
        """Total travelled distance [m]."""
        return float(sum(seg.length for seg in self._segments))

    def _samples(self, t) -> tuple:
        t = np.ascontiguousarray(np.atleast_1d(np.asarray(t, dtype=float)))
        out = [np.empty(t.shape) for _ in range(5)]
        direction = np.empty(t.shape, dtype=np.intc)
        status = self._lib.pt_reference_samples(
            ctypes.byref(self.struct), native.dptr(t), t.size, *(native.dptr(a) for a in out),
            direction.ctypes.data_as(ctypes.POINTER(ctypes.c_int)))
        if status:
            raise ReferencePathError(f"sampling the reference: "
                                     f"{native.STATUS.get(status, status)}")
        return (*out, direction)

    def sample(self, t):
        """Reference at times ``t`` [s] (array): ``(x, y, theta, v, w)``.

        ``theta`` is continuous (not wrapped). Before ``t0`` the reference rests at the start,
        after :attr:`t_end` at the goal with v = w = 0.
        """
        return self._samples(t)[:5]

    def direction_at(self, t) -> np.ndarray:
        """Direction at times ``t``: +1 push, -1 pull, 0 at rest (dwell, before start, after goal).
        """
        return self._samples(t)[5].astype(int)

    def pull_intervals(self) -> list[tuple[float, float]]:
        """Start and end times [s] of every maximal pulling run (consecutive pulling segments)."""
        cap = self.struct.n_phases + 1
        t_a, t_b = np.zeros(cap), np.zeros(cap)
        count = self._lib.pt_reference_pull_intervals(ctypes.byref(self.struct),
                                                      native.dptr(t_a), native.dptr(t_b), cap)
        return [(float(a), float(b)) for a, b in zip(t_a[:count], t_b[:count], strict=True)]

    def sample_at(self, t: float) -> ReferenceSample:
        """Reference at one time ``t`` [s] as plain floats (the scalar form of :meth:`sample`).

        Returns
        -------
        ReferenceSample
            Pose, velocities and direction (:data:`REST` during a cusp dwell, before ``t0`` and
            from :attr:`t_end` on, where v = w = 0).
        """
        status = self._lib.pt_reference_sample(ctypes.byref(self.struct), float(t),
                                               ctypes.byref(self._sample))
        if status:
            raise ReferencePathError(f"sampling the reference at t = {t!r} s: "
                                     f"{native.STATUS.get(status, status)}")
        s = self._sample
        return ReferenceSample(s.x, s.y, s.theta, s.v, s.w, int(s.direction))


def _rebuild(start, segments, speed, cusp_dwell, t0, previous_direction) -> Reference:
    """A pickled :class:`Reference` rebuilt (its C table is made again)."""
    return Reference(start, segments, speed, cusp_dwell, t0, previous_direction)


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

