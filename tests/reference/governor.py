"""The slip governor's limit written in Python: the reference the engine's
(``core/csrc/governor.c`` ``pt_governor_limit``, :class:`pushtrain.core.governor.SlipGovernor`)
is held equal to, bit for bit (``tests/core/test_governor.py``, the master's governed runs).
"""

from __future__ import annotations

import math

import numpy as np

from pushtrain.core.governor import GovernorConfig, lateral_forces


class SlipGovernor:
    """Limits command changes so that the predicted lateral forces stay within friction."""

    def __init__(self, config: GovernorConfig):
        self.config = config
        self._limits = config.limits
        self.reset()

    def reset(self, v0: float = 0.0, w0: float = 0.0) -> None:
        self.v_est, self.w_est = float(v0), float(w0)
        self.v_prev, self.w_prev = float(v0), float(w0)
        self.saturated = 0
        self.limited = 0

    def _robot_acc(self, v_cmd, w_cmd):
        cfg = self.config
        dv = min(max((v_cmd - self.v_est) / cfg.tau, -cfg.acc_max), cfg.acc_max)
        dw = min(max((w_cmd - self.w_est) / cfg.tau, -cfg.alpha_max), cfg.alpha_max)
        return dv, dw

    def _forces(self, phi, v_cmd, w_cmd):
        dv, dw = self._robot_acc(v_cmd, w_cmd)
        cfg = self.config
        return lateral_forces(phi, self.v_est, self.w_est, dv, dw, cfg.geometry, cfg.mass,
                              cfg.inertia)

    def limit(self, phi, v_cmd: float, w_cmd: float, dt: float):
        """The command to send instead of (v_cmd, w_cmd) given measured joint angles ``phi``.

        ``dt`` [s] is the control period over which the robot-velocity estimate advances.
        """
        def within(scale: float) -> bool:
            v = self.v_prev + scale * (v_cmd - self.v_prev)
            w = self.w_prev + scale * (w_cmd - self.w_prev)
            return bool(np.all(np.abs(self._forces(phi, v, w)) <= self._limits))

        s = 1.0
        if not within(1.0):
            self.limited += 1
            if not within(0.0):
                s = 0.0  # velocity-dependent forces alone exceed the limit: hold the command
                self.saturated += 1
            else:  # the forces are monotone enough along the segment: bisect for the largest s
                lo, hi = 0.0, 1.0
                for _ in range(30):
                    mid = 0.5 * (lo + hi)
                    lo, hi = (mid, hi) if within(mid) else (lo, mid)
                s = lo
        v_out = self.v_prev + s * (v_cmd - self.v_prev)
        w_out = self.w_prev + s * (w_cmd - self.w_prev)
        # advance the robot-velocity estimate with the governor's own model: the exact step of
        # the first-order lag, then the rate limits
        cfg = self.config
        decay = 1.0 - math.exp(-dt / cfg.tau)
        self.v_est += min(max((v_out - self.v_est) * decay, -cfg.acc_max * dt), cfg.acc_max * dt)
        self.w_est += min(max((w_out - self.w_est) * decay, -cfg.alpha_max * dt),
                          cfg.alpha_max * dt)
        self.v_prev, self.w_prev = v_out, w_out
        return v_out, w_out
