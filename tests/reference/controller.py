"""The backward-motion control law in plain Python: the reference the compiled law
(``core/csrc/control.c``, :class:`~pushtrain.core.controller.Controller`) is held
equal to, bit for bit.

:func:`kanayama` is the paper's Eq. 3-4, :class:`BackwardController` the whole law (last
trailer's pose, Kanayama on the leading body, inverse chain kinematics, speed and rate limits)
as :mod:`pushtrain.core.controller` describes it, with its settings
(:class:`~pushtrain.core.controller.ControllerConfig`), modes and diagnostics
(:class:`~pushtrain.core.controller.ControlInfo`). The product computes the law in C only.
SI units, radians.
"""

from __future__ import annotations

import logging
from math import cos, isfinite, sin

from pushtrain.core.controller import (
    MODE_PULL,
    MODE_PUSH,
    MODE_REST,
    ControlInfo,
    ControllerConfig,
    Gains,
)
from pushtrain.core.kinematics import robot_velocity_from_last, wrap_scalar
from pushtrain.core.reference import ReferenceSample
from pushtrain.core.segment import PULL, PUSH, REST
from pushtrain.core.tracking import TrackingLoop
from pushtrain.errors import ControllerError

__all__ = ["BackwardController", "kanayama"]

logger = logging.getLogger(__name__)


def kanayama(x_e: float, y_e: float, th_e: float, u_d: float, w_d: float,
             gains: Gains) -> tuple[float, float]:
    """Kanayama's tracking law (the paper's Eq. 3-4) in the tracked body's frame.

    ``x_e, y_e`` [m] are the reference position in that frame (along and left of the body),
    ``th_e`` [rad] the heading error (reference minus body, wrapped), ``u_d`` [m/s] and ``w_d``
    [rad/s] the reference speed (> 0: the law is stable only for forward travel in this frame,
    Eq. 13) and yaw rate. Returns the body's (u [m/s], w [rad/s])::

        u = u_d cos(th_e) + K_x x_e
        w = w_d + u_d (K_y y_e + K_theta sin(th_e))
    """
    return (u_d * cos(th_e) + gains.k_x * x_e,
            w_d + u_d * (gains.k_y * y_e + gains.k_theta * sin(th_e)))



class BackwardController:
    """Backward-motion controller: Kanayama on the leading body + inverse chain kinematics.

    See :mod:`pushtrain.core.controller` for the scheme. Stateful only through the previous
    command (for the optional rate limits); call :meth:`reset` when a run restarts.

    Parameters
    ----------
    config : ControllerConfig
    """

    def __init__(self, config: ControllerConfig):
        if not isinstance(config, ControllerConfig):
            raise ControllerError(f"config = {config!r}: must be a ControllerConfig")
        self.config = config
        self.n = config.geometry.n
        self._front = [float(a) for a in config.geometry.front]
        self._rear = [float(a) for a in config.geometry.rear]
        self.gains = Gains(float(config.k_x), float(config.k_y), float(config.k_theta))
        self._vmax, self._wmax = float(config.v_max), float(config.w_max)
        self._amax = None if config.acc_max is None else float(config.acc_max)
        self._alphamax = None if config.alpha_max is None else float(config.alpha_max)
        self._rest = float(config.rest_speed)
        self.guide_geometry = config.geometry
        self._loop: TrackingLoop | None = None  # command_from's loop of its last reference
        self.reset()

    @property
    def state(self) -> tuple:
        """The rate limits' memory ``(v_prev [m/s], w_prev [rad/s], t_prev [s] or None)``: what
        :meth:`reset` takes to resume a run from here."""
        return self._v_prev, self._w_prev, self._t_prev

    def sent(self, v0: float, w0: float) -> None:
        """Record the command actually sent after an outer limiter (e.g. the slip governor), so
        the rate limits continue from it."""
        self._v_prev, self._w_prev = float(v0), float(w0)

    def reset(self, v0: float = 0.0, w0: float = 0.0, t: float | None = None) -> None:
        """Forget the history: the previous command becomes ``(v0, w0)`` [m/s, rad/s] at ``t`` [s].

        With ``t=None`` (the default) the first call afterwards is not rate limited, its time step
        being unknown; pass the start time to rate-limit it from ``(v0, w0)``.
        """
        self._v_prev, self._w_prev, self._t_prev = float(v0), float(w0), t

    # -- kinematics on plain floats (equal to kinematics.body_positions / inverse_velocities) --

    def last_trailer_pose(self, x0: float, y0: float, theta0: float, phi) -> tuple:
        """Pose (x_n, y_n, theta_n) [m, m, rad] of trailer n from the robot pose and joint angles.

        ``theta_i = theta_{i-1} - phi_i`` (``theta_n`` continuous in theta_0, not wrapped); the
        offset of trailer n from the robot summed link by link, ``R_{i-1} e_{i-1} + F_i e_i``,
        then added to the robot's position (``pt_chain_positions``).
        """
        th, dx, dy = float(theta0), 0.0, 0.0
        front, rear = self._front, self._rear
        for i in range(self.n):
            c, s = cos(th), sin(th)
            th -= phi[i]
            dx -= rear[i] * c + front[i] * cos(th)
            dy -= rear[i] * s + front[i] * sin(th)
        return float(x0) + dx, float(y0) + dy, th

    def robot_velocity(self, phi, v_n: float, w_n: float) -> tuple:
        """Robot (v0 [m/s], w0 [rad/s]) making trailer n move with (v_n, w_n) (Step 3, Eq. 5)."""
        return robot_velocity_from_last(phi, v_n, w_n, self._front, self._rear)

    # -- the control law --

    def command(self, t: float, measurement, ref: ReferenceSample, leader=None):
        """Robot command for the measured state and the reference at time ``t``.

        Parameters
        ----------
        t : float
            Time [s] (used by the rate limits only).
        measurement
            Object with ``x0, y0, theta0`` (measured robot pose [m, m, rad]) and ``phi``
            (measured joint angles, sequence of n floats [rad]), e.g.
            :class:`pushtrain.core.sensors.Measurement`. If it has a ``last_pose``
            ``(x_n, y_n, theta_n)`` that is not ``None``, that direct measurement of the last
            trailer replaces the estimate from the joint angles (Step 2); Step 3 always uses
            ``phi``.
        ref : ReferenceSample
            The last trailer's reference at ``t``.
        leader : ReferenceSample or None
            Only needed while pulling: the robot's own reference at ``t``, from
            :class:`~pushtrain.core.pulling.PullGuide` built with :attr:`guide_geometry`.
            :class:`~pushtrain.core.tracking.TrackingLoop` (or :meth:`command_from`) fills it.

        Returns
        -------
        v0_cmd : float
            Robot longitudinal speed command [m/s].
        w0_cmd : float
            Robot yaw-rate command [rad/s].
        info : ControlInfo
        """
        phi = measurement.phi
        if len(phi) != self.n:
            raise ControllerError(
                f"measurement.phi has {len(phi)} joint angles; the controller's chain has {self.n}"
            )
        x_n, y_n, th_n = self._last_pose(t, measurement)
        direction = ref.direction
        if direction == REST or abs(ref.v) <= self._rest:
            mode = MODE_REST
            x_e = y_e = th_e = u_ref = w_ref = v_raw = w_raw = 0.0
        elif direction == PUSH:
            mode = MODE_PUSH
            x_e, y_e, th_e, u_ref, w_ref = self._push(ref, x_n, y_n, th_n)
            v_raw, w_raw = self.robot_velocity(phi, -u_ref, w_ref)  # Eq. 5
        elif direction == PULL:
            mode = MODE_PULL
            if leader is None:
                raise ControllerError(
                    f"pulling at t = {t!r} s needs the robot's reference `leader` "
                    "(PullGuide(reference, controller.guide_geometry).sample_at(t));"
                    " use command_from(reference, t, measurement)"
                )
            x_e, y_e, th_e, u_ref, w_ref = self._pull(leader, measurement)
            v_raw, w_raw = u_ref, w_ref
        else:
            raise ControllerError(
                f"ref.direction = {direction!r}: allowed are +1 (push), -1 (pull), 0 (rest)"
            )
        v, w, scale = self._limit(t, v_raw, w_raw)
        info = ControlInfo(mode, x_e, y_e, th_e, x_n, y_n, th_n, u_ref, w_ref, v_raw, w_raw, scale)
        return v, w, info

    def _last_pose(self, t: float, measurement) -> tuple:
        """The last trailer's pose: measured directly if the measurement has it, else estimated
        from the robot pose and the joint angles (Step 2); refuses a non-finite one."""
        x0, y0, th0 = measurement.x0, measurement.y0, measurement.theta0
        last = getattr(measurement, "last_pose", None)
        if last is None:
            x_n, y_n, th_n = self.last_trailer_pose(x0, y0, th0, measurement.phi)
        else:
            x_n, y_n, th_n = last
        if not (isfinite(x_n) and isfinite(y_n) and isfinite(th_n)):
            raise ControllerError(
                f"non-finite measurement at t = {t!r} s: robot pose ({x0!r}, {y0!r}, {th0!r}),"
                f" phi = {list(measurement.phi)!r}"
            )
        return x_n, y_n, th_n

    def _push(self, ref: ReferenceSample, x_n: float, y_n: float, th_n: float) -> tuple:
        """Kanayama on trailer n in its direction-of-travel frame (heading theta_n + pi, speed
        u = -v_n, so u_d = -v_d > 0): errors (Eq. 2) and the law's (u, w)."""
        dx, dy = ref.x - x_n, ref.y - y_n
        c, s = cos(th_n), sin(th_n)
        x_e = -(c * dx + s * dy)
        y_e = s * dx - c * dy
        th_e = wrap_scalar(ref.theta - th_n)
        return (x_e, y_e, th_e) + kanayama(x_e, y_e, th_e, -ref.v, ref.w, self.gains)

    def _pull(self, leader: ReferenceSample, measurement) -> tuple:
        """Kanayama on the robot in its own forward frame along its own reference ``leader``:
        errors (Eq. 2) and the law's (u, w)."""
        x0, y0, th0 = measurement.x0, measurement.y0, measurement.theta0
        dx, dy = leader.x - x0, leader.y - y0
        c, s = cos(th0), sin(th0)
        x_e = c * dx + s * dy
        y_e = -s * dx + c * dy
        th_e = wrap_scalar(leader.theta - th0)
        return (x_e, y_e, th_e) + kanayama(x_e, y_e, th_e, abs(leader.v), leader.w, self.gains)

    def command_from(self, reference, t: float, measurement):
        """:meth:`command` with ``ref`` and ``leader`` taken from ``reference`` at ``t``.

        ``reference`` is a :class:`~pushtrain.core.reference.Reference` or
        :class:`~pushtrain.core.sampled_reference.SampledReference`; the samples come from a
        :class:`~pushtrain.core.tracking.TrackingLoop` of this controller and ``reference``,
        kept while the calls pass the same reference object.
        """
        if self._loop is None or self._loop.reference is not reference:
            self._loop = TrackingLoop(self, reference)
        return self._loop.command(t, measurement)[:3]

    def _limit(self, t: float, v: float, w: float):
        """Apply the common-factor speed limits and the optional rate limits."""
        scale = max(1.0, abs(v) / self._vmax, abs(w) / self._wmax)
        if not isfinite(scale):
            raise ControllerError(f"non-finite command ({v!r}, {w!r}) at t = {t!r} s")
        v /= scale
        w /= scale
        if self._amax is not None or self._alphamax is not None:
            t_prev = self._t_prev
            if t_prev is not None and t > t_prev:
                dt = t - t_prev
                dv, dw = v - self._v_prev, w - self._w_prev
                r = 1.0
                if self._amax is not None:
                    r = max(r, abs(dv) / (self._amax * dt))
                if self._alphamax is not None:
                    r = max(r, abs(dw) / (self._alphamax * dt))
                v, w = self._v_prev + dv / r, self._w_prev + dw / r
            elif t_prev is not None and t < t_prev:
                logger.debug("time went back from %r s to %r s: rate limits restart", t_prev, t)
        self._v_prev, self._w_prev, self._t_prev = v, w, t
        return v, w, scale
