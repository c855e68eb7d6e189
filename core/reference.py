"""Time-parameterized reference for the last trailer (Step 1 of the paper).

The reference is the contract between :mod:`pushtrain.planner` (which fills it from a Reeds-Shepp
path) and the co-simulation master (which samples it every communication step).

Conventions are the chain's (see :mod:`pushtrain.core.kinematics`): ``theta`` is the last
trailer's heading pointing toward the robot, ``v`` its signed longitudinal speed (negative when
pushing: the trailer leads), ``w = d(theta)/dt``. Eq. (1) of the paper in this +x convention::

    dx/dt = v cos(theta),  dy/dt = v sin(theta),  d(theta)/dt = w

The reference runs through line and arc :class:`~pushtrain.core.segment.Segment` objects at
constant speed, each in one direction. Direction changes (cusps) are stops: the reference rests
for ``cusp_dwell`` seconds and continues the other way. A reference given as samples is
:class:`~pushtrain.core.sampled_reference.SampledReference`.
"""

from __future__ import annotations

import ctypes
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from pushtrain.defaults import CUSP_DWELL, REFERENCE_SPEED
from pushtrain.errors import ReferencePathError

from . import native
from .kinematics import wrap_angle
from .segment import Segment, segment_struct

__all__ = ["Reference", "ReferenceSample", "path_points"]


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
        :data:`~pushtrain.core.segment.PUSH` (+1), :data:`~pushtrain.core.segment.PULL` (-1) or
        :data:`~pushtrain.core.segment.REST` (0).
    """

    x: float
    y: float
    theta: float
    v: float
    w: float
    direction: int


def path_points(start, segments, spacing: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """Positions (x, y) [m] every ``spacing`` metres along ``segments`` from ``start``
    (x, y, theta), both ends included."""
    ref = Reference.from_segments(tuple(start[:3]), list(segments), speed=1.0, cusp_dwell=0.0)
    s = np.linspace(0.0, ref.t_end, max(2, int(ref.t_end / spacing) + 1))
    x, y, _, _, _ = ref.sample(s)
    return np.asarray(x), np.asarray(y)


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
            Pose, velocities and direction (:data:`~pushtrain.core.segment.REST` during a cusp
            dwell, before ``t0`` and from :attr:`t_end` on, where v = w = 0).
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
