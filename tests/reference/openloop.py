"""The open-loop profiles written out in Python: the reference ``core/csrc/openloop.c`` (through
:class:`pushtrain.core.openloop.Profile`) is held equal to, bit for bit
(``tests/core/test_openloop.py``). SI units, radians."""

from __future__ import annotations


def rotation_yaw_rate(t: float, w_max: float, alpha: float, hold: float = 0.0) -> float:
    """The yaw rate [rad/s] of the robot's swing at ``t`` [s]: each half period
    ``2 w_max / alpha + hold`` it ramps at ``alpha`` [rad/s^2] to ``w_max`` [rad/s], holds for
    ``hold`` [s] and ramps back to 0 (never below); every other half period negated; 0 before
    t = 0."""
    if t < 0:
        return 0.0
    ramp = w_max / alpha
    k, tau = divmod(t, 2.0 * w_max / alpha + hold)
    sign = 1.0 if int(k) % 2 == 0 else -1.0
    if tau < ramp:
        w = alpha * tau
    elif tau < ramp + hold:
        w = w_max
    else:
        w = max(0.0, w_max - alpha * (tau - (ramp + hold)))
    return sign * w
