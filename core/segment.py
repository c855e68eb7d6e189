"""One piece of the last trailer's path: a line or an arc travelled in one direction.

Conventions are the chain's (see :mod:`pushtrain.core.kinematics`): ``theta`` is the last
trailer's heading pointing toward the robot. A :class:`Segment` is travelled trailer first
(:data:`PUSH`: the robot pushes, v < 0) or robot first (:data:`PULL`, v > 0); its
``curvature`` is d(theta)/ds per metre *travelled* (s increases in both directions), so
``w = curvature * |v|``. The reference built from segments is
:class:`~pushtrain.core.reference.Reference`; :data:`REST` is its direction while it rests.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from pushtrain.errors import ReferencePathError

from . import native

__all__ = ["PULL", "PUSH", "REST", "Segment", "segment_struct"]

PUSH = +1
"""Direction of a segment travelled trailer first (the robot pushes): v < 0."""
PULL = -1
"""Direction of a segment travelled robot first (the robot pulls): v > 0."""


REST = 0
"""Direction value while the reference rests (cusp dwell, before the start, after the goal)."""


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

    def to_dict(self) -> dict:
        """Plain data (JSON-ready), what :meth:`from_dict` reads: ``kind``, ``length`` [m],
        ``curvature`` [1/m], ``direction`` ('push' or 'pull'), and ``speed`` [m/s] if set."""
        return {"kind": self.kind, "length": float(self.length),
                "curvature": float(self.curvature),
                "direction": "push" if self.direction == PUSH else "pull",
                **({} if self.speed is None else {"speed": float(self.speed)})}

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


_KINDS = {"line": 0, "arc": 1}


def segment_struct(segment: Segment):
    """The C ``PtSegment`` of a :class:`Segment` (speed 0: the reference's default)."""
    if not isinstance(segment, Segment):
        raise ReferencePathError(f"segments must be Segment objects, got "
                                 f"{type(segment).__name__}")
    return native.PtSegment(float(segment.length), float(segment.curvature),
                            0.0 if segment.speed is None else float(segment.speed),
                            int(segment.direction), _KINDS[segment.kind])
