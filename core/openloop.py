"""Open-loop robot command profiles (no tracking), e.g. the pure rotation of the paper's Sec. 4.4.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["RotationProfile", "ConstantCommand"]


@dataclass(frozen=True)
class RotationProfile:
    """Periodic pure rotation of the robot (Fig. 15): v0 = 0 and a trapezoidal yaw rate.

    Each half period the yaw rate ramps with angular acceleration ``alpha`` [rad/s^2] to
    ``+w_max`` [rad/s], holds for ``hold`` [s] and ramps back to 0; the next half period does the
    same with ``-w_max``, so the robot swings back and forth. Has the controller interface the
    master expects (``n``, ``guide_geometry``, ``command``).
    """

    n: int
    w_max: float
    alpha: float
    hold: float = 0.0
    guide_geometry: None = None

    def __post_init__(self):
        for name in ("w_max", "alpha"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} = {value!r}: must be finite and > 0")
        if not (math.isfinite(self.hold) and self.hold >= 0):
            raise ValueError(f"hold = {self.hold!r} s: must be finite and >= 0")

    @property
    def half_period(self) -> float:
        """Duration [s] of one swing: ramp up, hold, ramp down."""
        return 2.0 * self.w_max / self.alpha + self.hold

    def yaw_rate(self, t: float) -> float:
        """Commanded yaw rate [rad/s] at time ``t`` [s]."""
        if t < 0:
            return 0.0
        ramp = self.w_max / self.alpha
        k, tau = divmod(t, self.half_period)
        sign = 1.0 if int(k) % 2 == 0 else -1.0
        if tau < ramp:
            w = self.alpha * tau
        elif tau < ramp + self.hold:
            w = self.w_max
        else:
            w = max(0.0, self.w_max - self.alpha * (tau - ramp - self.hold))
        return sign * w

    def command(self, t, measurement, ref, leader=None):
        return 0.0, self.yaw_rate(t), None


@dataclass(frozen=True)
class ConstantCommand:
    """The robot drives with a fixed (v0 [m/s], w0 [rad/s]): open-loop pushing or holding still.

    Has the controller interface the master expects (``n``, ``guide_geometry``, ``command``).
    """

    n: int
    v0: float = 0.0
    w0: float = 0.0
    guide_geometry: None = None

    def command(self, t, measurement, ref, leader=None):
        return self.v0, self.w0, None
