"""Backward-motion controller of a robot with n off-hooked trailers (Steps 2-3 of the paper).

Called once per communication step (5 ms) with the *measured* state (robot pose from localization,
joint angles from the potentiometers) and the last trailer's reference sample, it returns the robot
command ``(v0, w0)``. Pure Python floats on the hot path: no fmpy, no per-call numpy allocation.

Pushing (direction PUSH, the last trailer leads, v_d < 0)
    1. The last trailer's pose from the measured robot pose and joint angles through the
       controller's own :class:`~pushtrain.core.kinematics.ChainGeometry`
       (``theta_i = theta_0 - sum_{k<=i} phi_k``, ``P_i = P_{i-1} - R_{i-1} e_{i-1} - F_i e_i``,
       as :func:`~pushtrain.core.kinematics.body_positions`).
    2. Kanayama's tracking law (Eq. 2-4) in the last trailer's *direction-of-travel* frame:
       heading ``theta_n + pi`` and speed ``u = -v_n``, so the reference speed ``u_d = -v_d > 0``.
       With ``th_t = theta_n + pi`` and the reference heading ``theta_d + pi``::

           x_e =  cos(th_t) (x_d - x_n) + sin(th_t) (y_d - y_n)
           y_e = -sin(th_t) (x_d - x_n) + cos(th_t) (y_d - y_n)
           theta_e = wrap(theta_d - theta_n)
           u_ref = u_d cos(theta_e) + K_x x_e                          (Eq. 3)
           w_ref = w_d + u_d (K_y y_e + K_theta sin(theta_e))          (Eq. 4)

       and the last trailer is asked for ``v_n = -u_ref``, ``w_n = w_ref``. In the chain frame
       (u_d < 0) the same law has a non-Hurwitz linearization (Eq. 13 with v_d < 0) and diverges.
    3. Inverse chain kinematics from trailer n to the robot
       (:func:`~pushtrain.core.kinematics.inverse_velocities`, Eq. 5 for D = F = R) with the
       measured joint angles gives ``(v0, w0)``. The joints then evolve as a chain *towed* by the
       last trailer, which is stable.

Pulling (direction PULL, the robot leads, v_d > 0)
    Prescribing the last trailer's motion while it moves toward the robot makes the joint
    dynamics unstable (linearizing ``phi_n' = w_{n-1} - w_n`` under the inverse map gives
    ``+(v_n / R_{n-1}) phi_n``: every joint ahead of a prescribed body jackknifes). So when pulling
    the robot leads: it tracks, with the same Kanayama law in its own forward frame (heading
    theta_0, speed v0 > 0), a reference of its own, ``leader``: the robot's motion that makes the
    towed chain bring the last trailer along its reference, computed backward in time from a
    straight chain at the end of each pulling run (:class:`~pushtrain.core.pulling.PullGuide`).
    Towing is stable, so errors of the chain behind the robot decay. Kanayama on the
    last trailer in its forward frame followed by the inverse map was rejected for the reason
    above (verified in the tests: it jackknifes).

At rest (direction REST, or |v_d| below ``rest_speed``: cusp dwells, before the start, at the goal)
the command is zero: no tracking law is evaluated, so nothing divides by v_d.

Limits: the command is scaled by one common factor so that |v0| <= v_max and |w0| <= w_max,
which keeps the curvature w0/v0 (and hence, through the linear chain map, the last trailer's
commanded curvature). Optional rate limits (acc_max, alpha_max) scale the *change* from the previous
command by one common factor as well.

Gains (defaults K_x = 1 1/s, K_y = 4 1/m², K_theta = 4 1/m): in Eq. 4 the lateral loop is
``y'' + u_d K_theta y' + u_d² K_y y = 0``, i.e. in travelled distance s: ``y_ss + K_theta y_s +
K_y y = 0``. K_theta = 2 sqrt(K_y) makes it critically damped with a double root at -sqrt(K_y)
= -2 per metre: lateral errors decay over about 0.5 m of travel, the order of the link D = 0.52 m,
so the commanded curvature for a 0.2 m offset (K_y y = 0.8 1/m) stays near the radius the chain can
turn (joint angles 2 atan(D kappa) below about 45 deg) and the robot limits are not hit all the
time. Kanayama's own example gains (K_y = 64, K_theta = 16) would ask for radii of 0.1 m.
K_x = 1 1/s settles along-track errors in about 1 s. With a directly measured last-trailer pose
the steady offset under a joint bias, sin(eps)/(D K_y), is 4.2 cm for 5 deg and 8.3 cm for 10 deg
with these gains; with the pose estimated from the biased joints it is about 4 times larger
(:func:`pushtrain.core.analysis.steady_lateral_error_estimated_pose`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from math import cos, isfinite, sin
from typing import NamedTuple

import numpy as np

from pushtrain.errors import ControllerError
from pushtrain.settings import angle_setting, setting
from pushtrain.validation import PositiveFloat

from .kinematics import ChainGeometry, robot_velocity_from_last, wrap_scalar
from .reference import PULL, PUSH, REST, ReferenceSample
from .tracking import TrackingLoop

__all__ = ["MODE_PULL", "MODE_PUSH", "MODE_REST", "BackwardController", "ControlInfo",
           "ControllerConfig", "Gains", "kanayama"]

logger = logging.getLogger(__name__)

MODE_REST = "rest"
"""Reference at rest: zero command."""
MODE_PUSH = "push"
"""Last trailer leads: Kanayama on trailer n in its direction-of-travel frame + inverse map."""
MODE_PULL = "pull"
"""Robot leads: Kanayama on the robot along its own pulling reference (PullGuide)."""


@dataclass(frozen=True)
class ControllerConfig:
    """Gains, model and limits of :class:`BackwardController`.

    Parameters
    ----------
    geometry : ChainGeometry
        The controller's own chain model (link lengths F_i, R_i [m]); it may differ from the plant.
    k_x : float
        Along-track gain K_x [1/s], > 0 (Eq. 3).
    k_y : float
        Lateral gain K_y [1/m²], > 0 (Eq. 4).
    k_theta : float
        Heading gain K_theta [1/m], > 0 (Eq. 4).
    v_max : float
        Robot speed limit [m/s], > 0 (Table: 0.1).
    w_max : float
        Robot yaw-rate limit [rad/s], > 0 (Table: 0.1).
    acc_max, alpha_max : float or None
        Rate limits of the command [m/s², rad/s²], > 0; ``None`` disables one. Default 0.2
        m/s² and 10 deg/s²: the paper keeps |alpha| <= 10 deg/s² to avoid lateral slip
        (Sec. 4.4).
    rest_speed : float
        |v_d| [m/s] at or below which the reference counts as resting (>= 0).

    The gains and rate limits are the scenario's ``[controller]`` section, ``v_max`` and
    ``w_max`` (as ``w_max_deg``) its ``[robot]`` section: generated from these declarations
    (:mod:`pushtrain.settings`), so the file's defaults are these.
    """

    geometry: ChainGeometry
    k_x: float = setting(1.0, PositiveFloat)
    k_y: float = setting(4.0, PositiveFloat)
    k_theta: float = setting(4.0, PositiveFloat)
    v_max: float = setting(0.1, PositiveFloat, part="robot")
    w_max: float = angle_setting(math.degrees(0.1), PositiveFloat, part="robot")
    acc_max: float | None = setting(0.2, PositiveFloat | None)
    alpha_max: float | None = angle_setting(10.0, PositiveFloat | None)
    rest_speed: float = 1e-9

    def __post_init__(self):
        if not isinstance(self.geometry, ChainGeometry):
            raise ControllerError(f"geometry = {self.geometry!r}: must be a ChainGeometry")
        for name in ("k_x", "k_y", "k_theta", "v_max", "w_max"):
            value = getattr(self, name)
            if not (
                isinstance(value, (int, float, np.floating, np.integer))
                and isfinite(value)
                and value > 0.0
            ):
                raise ControllerError(f"{name} = {value!r}: must be a finite number > 0")
        for name in ("acc_max", "alpha_max"):
            value = getattr(self, name)
            if value is not None and not (isfinite(value) and value > 0.0):
                raise ControllerError(f"{name} = {value!r}: must be None or a finite number > 0")
        if not (isfinite(self.rest_speed) and self.rest_speed >= 0.0):
            raise ControllerError(f"rest_speed = {self.rest_speed!r} m/s: must be finite and >= 0")

    @classmethod
    def uniform(cls, n_trailers: int, link: float = 0.52, **kwargs) -> ControllerConfig:
        """Config for a chain with every F_i = R_i = ``link`` [m]; ``kwargs`` as the fields."""
        try:
            geometry = ChainGeometry.uniform(n_trailers, link)
        except ValueError as exc:
            raise ControllerError(str(exc)) from exc
        return cls(geometry=geometry, **kwargs)


class Gains(NamedTuple):
    """Kanayama's gains: K_x [1/s] (Eq. 3), K_y [1/m²] and K_theta [1/m] (Eq. 4)."""

    k_x: float
    k_y: float
    k_theta: float


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


class ControlInfo(NamedTuple):
    """Diagnostics of one :meth:`BackwardController.command` call.

    ``x_e, y_e, theta_e`` [m, m, rad] are the Kanayama errors of the tracked body (trailer n in its
    direction-of-travel frame when pushing, the robot when pulling, zero at rest); ``x_n, y_n,
    theta_n`` the last trailer's pose estimated from the measurement [m, m, rad]; ``v_ref, w_ref``
    the Kanayama output [m/s, rad/s] in the tracked body's frame; ``v_raw, w_raw`` the robot command
    before the limits; ``scale`` >= 1 the common speed-limit divisor.
    """

    mode: str
    x_e: float
    y_e: float
    theta_e: float
    x_n: float
    y_n: float
    theta_n: float
    v_ref: float
    w_ref: float
    v_raw: float
    w_raw: float
    scale: float


class BackwardController:
    """Backward-motion controller: Kanayama on the leading body + inverse chain kinematics.

    See the module docstring for the scheme. Stateful only through the previous command (for the
    optional rate limits); call :meth:`reset` when a run restarts.

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

        ``theta_n = theta_0 - sum(phi)`` is continuous in theta_0 (not wrapped).
        """
        x, y, th = float(x0), float(y0), float(theta0)
        front, rear = self._front, self._rear
        c, s = cos(th), sin(th)
        for i in range(self.n):
            x -= rear[i] * c
            y -= rear[i] * s
            th -= phi[i]
            c, s = cos(th), sin(th)
            x -= front[i] * c
            y -= front[i] * s
        return x, y, th

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
            :class:`pushtrain.cosim.sensors.Measurement`. If it has a ``last_pose``
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
        :class:`~pushtrain.core.reference.SampledReference`; the samples come from a
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
