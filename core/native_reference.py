"""The last trailer's line/arc reference in C.

:class:`NativeReference` is :class:`~pushtrain.core.reference.Reference` held in the C phase
table of ``core/csrc/control.c`` (the same numbers, tested equal), extendable segment by
segment: a planner appends an edge's segments to the reference so far, or starts a
:meth:`~NativeReference.continuation` at the end of it. (The robot's reference while pulling
is :class:`~pushtrain.core.pulling.PullGuide`, computed and sampled in C.)

It keeps its C struct and the numpy array behind it alive; the fast closed loop
(:mod:`pushtrain.core.engine`) passes the struct to C as it is.
"""

from __future__ import annotations

import ctypes
from collections.abc import Sequence

import numpy as np

from pushtrain.errors import ReferencePathError

from . import native
from .reference import Reference, ReferenceSample, Segment

__all__ = ["NativeReference", "segment_struct"]

_KINDS = {"line": 0, "arc": 1}


def segment_struct(segment: Segment) -> native.PtSegment:
    """The C ``PtSegment`` of a :class:`~pushtrain.core.reference.Segment` (speed 0: the
    reference's default)."""
    if not isinstance(segment, Segment):
        raise ReferencePathError(f"segments must be Segment objects, got "
                                 f"{type(segment).__name__}")
    return native.PtSegment(float(segment.length), float(segment.curvature),
                            0.0 if segment.speed is None else float(segment.speed),
                            int(segment.direction), _KINDS[segment.kind])


class NativeReference:
    """A line/arc reference of the last trailer in C (:class:`Reference`'s table and sampling).

    Parameters
    ----------
    start : (x, y, theta)
        Start pose [m, m, rad] at ``t0``.
    speed : float
        Default |v| [m/s] of segments without their own, > 0.
    cusp_dwell : float
        Rest [s] at every direction change, >= 0.
    t0 : float
        Start time [s].
    previous_direction : int
        Direction of the motion before ``t0`` (0: none). A first segment of the other
        direction starts with a dwell, as inside one longer reference.
    segments : sequence of Segment
        Appended at once (more can follow with :meth:`append`).
    """

    def __init__(self, start: Sequence[float], speed: float = 0.1, cusp_dwell: float = 1.0,
                 t0: float = 0.0, previous_direction: int = 0,
                 segments: Sequence[Segment] = ()):
        self._lib = native.load()
        self._table = np.zeros((max(8, 2 * len(segments) + 2), 7))
        self.struct = native.PtReference()
        start_arr = np.array([float(a) for a in start], dtype=float) if len(start) == 3 else None
        if start_arr is None:
            raise ReferencePathError(f"start = {start!r}: need three finite numbers (x, y, theta)")
        status = self._lib.pt_reference_init(
            ctypes.byref(self.struct), self._phases_ptr(), self._table.shape[0],
            native.dptr(start_arr), float(speed), float(cusp_dwell), float(t0),
            int(previous_direction))
        if status:
            raise ReferencePathError(
                f"reference start = {tuple(start)!r}, speed = {speed!r} m/s, cusp_dwell = "
                f"{cusp_dwell!r} s, t0 = {t0!r} s, previous_direction = {previous_direction!r}: "
                "need a finite start and t0, speed > 0, cusp_dwell >= 0 and a direction of "
                "+1, -1 or 0")
        self.start = tuple(float(a) for a in start_arr)
        self.segments: list[Segment] = []
        self._sample = native.PtSample()
        self.extend(segments)

    @classmethod
    def from_reference(cls, reference: Reference) -> NativeReference:
        """The C table of a Python :class:`Reference`."""
        return cls(reference.start, reference.speed, reference.cusp_dwell, reference.t0,
                   segments=reference.segments)

    def _phases_ptr(self):
        return self._table.ctypes.data_as(ctypes.POINTER(native.PtPhase))

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
            raise ReferencePathError(f"segment {segment!r} refused by the C reference: "
                                     f"{native.STATUS.get(status, status)}")
        self.segments.append(segment)

    def extend(self, segments: Sequence[Segment]) -> None:
        """Append segments in order."""
        for segment in segments:
            self.append(segment)

    def copy(self) -> NativeReference:
        """An independent copy (for branching: extend the copy, keep this one)."""
        other = NativeReference.__new__(NativeReference)
        other._lib = self._lib
        other._table = self._table.copy()
        other.struct = native.PtReference()
        ctypes.memmove(ctypes.byref(other.struct), ctypes.byref(self.struct),
                       ctypes.sizeof(native.PtReference))
        other.struct.phases = other._phases_ptr()
        other.start = self.start
        other.segments = list(self.segments)
        other._sample = native.PtSample()
        return other

    def continuation(self, segments: Sequence[Segment] = ()) -> NativeReference:
        """A new reference that starts where this one ends (pose, time :attr:`t_end`, last
        direction) with ``segments``: sampled at or after :attr:`t_end` it equals this
        reference extended by the same segments, bit for bit."""
        s = self.struct
        return NativeReference((s.x_end, s.y_end, s.theta_end), s.speed, s.cusp_dwell, s.t_end,
                               s.last_direction, segments)

    # ------------------------------------------------------------------ queries
    @property
    def t0(self) -> float:
        """Start time [s]."""
        return float(self.struct.t0)

    @property
    def t_end(self) -> float:
        """Time [s] the last segment ends (the reference rests from then on)."""
        return float(self.struct.t_end)

    @property
    def speed(self) -> float:
        """Default |v| [m/s]."""
        return float(self.struct.speed)

    @property
    def cusp_dwell(self) -> float:
        """Rest at direction changes [s]."""
        return float(self.struct.cusp_dwell)

    @property
    def end_pose(self) -> tuple[float, float, float]:
        """Pose (x, y, theta) [m, m, rad] at :attr:`t_end`, theta continuous."""
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

    def sample_at(self, t: float) -> ReferenceSample:
        """Reference at one time ``t`` [s] (:meth:`Reference.sample_at`)."""
        status = self._lib.pt_reference_sample(ctypes.byref(self.struct), float(t),
                                               ctypes.byref(self._sample))
        if status:
            raise ReferencePathError(f"sampling the reference at t = {t!r} s: "
                                     f"{native.STATUS.get(status, status)}")
        s = self._sample
        return ReferenceSample(s.x, s.y, s.theta, s.v, s.w, int(s.direction))

    def pull_intervals(self) -> list[tuple[float, float]]:
        """Start and end times [s] of every maximal pulling run."""
        cap = self.struct.n_phases + 1
        t_a, t_b = np.zeros(cap), np.zeros(cap)
        count = self._lib.pt_reference_pull_intervals(ctypes.byref(self.struct),
                                                      native.dptr(t_a), native.dptr(t_b), cap)
        return [(float(a), float(b)) for a, b in zip(t_a[:count], t_b[:count], strict=True)]
