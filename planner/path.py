"""The planner's result: a line-and-arc path of the last trailer (:class:`PlannedPath`).

Poses use the chain convention of :mod:`pushtrain.core.kinematics` (theta points toward the
robot). Segments are :class:`pushtrain.core.segment.Segment` objects, so the path turns into
the co-simulation master's :class:`~pushtrain.core.reference.Reference` directly.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from pushtrain.core.reference import Reference
from pushtrain.core.segment import PULL, PUSH, Segment
from pushtrain.defaults import CUSP_DWELL, REFERENCE_SPEED
from pushtrain.errors import PlanningInputError

__all__ = ["PlannedPath", "dense_samples", "reference_times", "FORMAT_VERSION"]

FORMAT_VERSION = 1
"""Version of the JSON layout written by :meth:`PlannedPath.to_json`."""


def dense_samples(start: Sequence[float], segments: Sequence[Segment], resolution: float):
    """Sample the path every <= ``resolution`` metres of travel, segment ends included.

    Returns
    -------
    s : ndarray (N,)
        Travelled distance [m] (increases through cusps).
    poses : ndarray (N, 3)
        (x, y, theta) [m, m, rad], chain convention, theta continuous.
    interval_segment : ndarray (N-1,) of int
        Index of the segment each interval [s_k, s_k+1] lies on.
    """
    ref = Reference.from_segments(start, segments, speed=1.0, cusp_dwell=0.0)
    pieces, seg_ids, s0 = [np.array([0.0])], [], 0.0
    for k, seg in enumerate(segments):
        m = max(1, int(np.ceil(seg.length / resolution - 1e-9)))
        pieces.append(s0 + seg.length * np.arange(1, m + 1) / m)
        seg_ids.append(np.full(m, k))
        s0 += seg.length
    s = np.concatenate(pieces)
    x, y, theta, _, _ = ref.sample(s)
    return s, np.column_stack([x, y, theta]), np.concatenate(seg_ids).astype(int)


def reference_times(segments: Sequence[Segment], speed: float, cusp_dwell: float, s):
    """Time [s] at which the reference of :class:`~pushtrain.core.reference.Reference` (t0 = 0)
    reaches the travelled distance ``s`` [m] (array); at a cusp the arrival (start of the dwell).

    Returns ``(t, knots)`` where ``knots = (t_knots, s_knots)`` is the piecewise-linear map
    t -> s (flat during dwells) for :func:`numpy.interp`.
    """
    t_k, s_k = [0.0], [0.0]
    t, pos, previous = 0.0, 0.0, None
    starts, ends, seg_t0, seg_speed = [], [], [], []
    for seg in segments:
        if previous is not None and seg.direction != previous:
            t += cusp_dwell
            t_k.append(t), s_k.append(pos)
        v = speed if seg.speed is None else seg.speed
        starts.append(pos), seg_t0.append(t), seg_speed.append(v)
        t += seg.length / v
        pos += seg.length
        ends.append(pos)
        t_k.append(t), s_k.append(pos)
        previous = seg.direction
    s = np.asarray(s, dtype=float)
    j = np.clip(np.searchsorted(np.array(ends), s, side="left"), 0, len(ends) - 1)
    times = np.array(seg_t0)[j] + (s - np.array(starts)[j]) / np.array(seg_speed)[j]
    return times, (np.array(t_k), np.array(s_k))


_MACHINE_DEPENDENT = ("time",)
"""Entries of ``info`` that depend on the machine and its load, not written to ``path.json``."""


@dataclass(eq=False)
class PlannedPath:
    """A planned line/arc path of the last trailer's axle midpoint.

    Parameters
    ----------
    start : (3,) array
        Start pose (x [m], y [m], theta [rad]) in the chain convention.
    segments : tuple of Segment
        Ordered lines and arcs; ``curvature`` is d(theta)/ds per metre travelled [1/m],
        ``direction`` PUSH (+1, trailer leads) or PULL (-1, robot leads).
    turning_radius : float
        Radius [m] the path was planned with (every arc has |curvature| = 1 / radius).
    start_headings : (n+1,) array or None
        Headings [rad] of robot and trailers at the start (the train's start configuration).
    resolution : float
        Spacing [m] of :attr:`poses`.
    info : dict
        Plain data about how the path was found (planner, times, attempts, ...).

    Attributes
    ----------
    s : (N,) array
        Travelled distance [m] at each dense pose.
    poses : (N, 3) array
        Dense poses (x, y, theta) of the last trailer, chain convention, theta continuous.
    cusps : (K,) int array
        Indices into :attr:`poses` where the direction changes.
    headings : (N, n+1) array or None
        Body headings [rad] from the planner's closed-loop train check (set by the planner):
        those of the simulated train at the time the reference passes each of :attr:`poses`
        (at a cusp: when it arrives). The simulated last trailer is near, not exactly at,
        those poses (its tracking error is in ``info["train_check"]``).
    """

    start: np.ndarray
    segments: tuple
    turning_radius: float
    start_headings: np.ndarray | None = None
    resolution: float = 0.01
    info: dict = field(default_factory=dict)
    headings: np.ndarray | None = None
    s: np.ndarray = field(init=False, repr=False)
    poses: np.ndarray = field(init=False, repr=False)
    cusps: np.ndarray = field(init=False, repr=False)
    interval_segment: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        self.start = np.asarray(self.start, dtype=float).reshape(3)
        self.segments = tuple(self.segments)
        if not self.segments:
            raise PlanningInputError("a planned path needs at least one segment")
        if self.start_headings is not None:
            self.start_headings = np.asarray(self.start_headings, dtype=float).reshape(-1)
        self.s, self.poses, self.interval_segment = dense_samples(
            self.start, self.segments, self.resolution
        )
        change = np.flatnonzero(np.diff(self.interval_segment) != 0) + 1
        self.cusps = np.array(
            [
                int(b)
                for b in change
                if self.segments[self.interval_segment[b]].direction
                != self.segments[self.interval_segment[b - 1]].direction
            ],
            dtype=int,
        )

    # ------------------------------------------------------------------ summaries
    @property
    def length(self) -> float:
        """Total travelled distance [m]."""
        return float(sum(seg.length for seg in self.segments))

    @property
    def goal(self) -> np.ndarray:
        """Final pose (x, y, theta) [m, m, rad], theta continuous from the start."""
        return self.poses[-1].copy()

    @property
    def n_cusps(self) -> int:
        """Number of direction changes."""
        return int(self.cusps.size)

    @property
    def push_length(self) -> float:
        """Distance travelled pushing [m]."""
        return float(sum(g.length for g in self.segments if g.direction == PUSH))

    @property
    def pull_length(self) -> float:
        """Distance travelled pulling [m]."""
        return float(sum(g.length for g in self.segments if g.direction == PULL))

    def joint_angles(self) -> np.ndarray | None:
        """Joint angles phi_i = theta_{i-1} - theta_i [rad] along the path, (N, n), if checked."""
        if self.headings is None:
            return None
        from pushtrain.core.kinematics import joint_angles

        return joint_angles(self.headings)

    # ------------------------------------------------------------------ conversion
    def to_reference(
        self, speed: float = REFERENCE_SPEED, cusp_dwell: float = CUSP_DWELL, t0: float = 0.0
    ) -> Reference:
        """The time-parameterized reference for the co-simulation master.

        Constant ``speed`` [m/s] on every segment (w_d = v_d * curvature; default the
        scenario's 0.08 m/s), a rest of ``cusp_dwell`` [s] at every direction change.
        """
        return Reference.from_segments(self.start, self.segments, speed, cusp_dwell, t0)

    def to_dict(self) -> dict:
        """Plain data (JSON-ready). The planning's wall time (``info["time"]``) is left out:
        ``path.json`` is a function of the scenario alone, the same on any machine and under
        any load."""
        return {
            "format": "pushtrain.planned_path",
            "version": FORMAT_VERSION,
            "start": [float(a) for a in self.start],
            "turning_radius": float(self.turning_radius),
            "start_headings": None
            if self.start_headings is None
            else [float(a) for a in self.start_headings],
            "resolution": float(self.resolution),
            "segments": [g.to_dict() for g in self.segments],
            "info": _plain({k: v for k, v in self.info.items() if k not in _MACHINE_DEPENDENT}),
        }

    @classmethod
    def from_dict(cls, data: dict) -> "PlannedPath":
        """Inverse of :meth:`to_dict`."""
        if data.get("format") != "pushtrain.planned_path":
            raise PlanningInputError(
                f"format = {data.get('format')!r}: expected 'pushtrain.planned_path'"
            )
        if int(data.get("version", -1)) != FORMAT_VERSION:
            raise PlanningInputError(
                f"version = {data.get('version')!r}: this reader understands {FORMAT_VERSION}"
            )
        directions = {"push": PUSH, "pull": PULL}
        segments = []
        for k, g in enumerate(data["segments"]):
            if g.get("direction") not in directions:
                raise PlanningInputError(
                    f"segments[{k}].direction = {g.get('direction')!r}: allowed 'push', 'pull'"
                )
            segments.append(
                Segment(g["kind"], float(g["length"]), float(g["curvature"]),
                        directions[g["direction"]], g.get("speed"))
            )
        return cls(
            np.asarray(data["start"], dtype=float),
            tuple(segments),
            float(data["turning_radius"]),
            None if data.get("start_headings") is None else np.asarray(data["start_headings"]),
            float(data.get("resolution", 0.01)),
            dict(data.get("info", {})),
        )

    def to_json(self, path: str | Path | None = None, indent: int = 2) -> str:
        """JSON text of :meth:`to_dict`; also written to ``path`` if given."""
        text = json.dumps(self.to_dict(), indent=indent)
        if path is not None:
            Path(path).write_text(text + "\n")
        return text

    @classmethod
    def from_json(cls, source: str | Path) -> "PlannedPath":
        """Read a path from JSON text or from a file path."""
        text = str(source)
        if not text.lstrip().startswith("{"):
            text = Path(source).read_text()
        return cls.from_dict(json.loads(text))


def _plain(value: Any):
    """Recursively convert numpy scalars/arrays in ``value`` to plain Python data."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value
