"""Backward-motion control law of a robot with n off-hooked trailers (Steps 2-3 of the paper):
its settings (:class:`ControllerConfig`), gains, modes and diagnostics (:class:`ControlInfo`).

The law is computed in C (``core/csrc/control.c``): by
:class:`~pushtrain.core.native_controller.NativeController` in the co-simulation, by the
closed-loop engine (:mod:`pushtrain.core.engine`) in the planner and by the controller FMU.
Called once per communication step (5 ms) with the *measured* state (robot pose from
localization, joint angles from the potentiometers) and the last trailer's reference sample, it
returns the robot command ``(v0, w0)``. The readable Python version the C is held equal to, bit
for bit, is the tests' ``tests/reference/controller.py``.

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

import math
from dataclasses import dataclass
from math import isfinite
from typing import NamedTuple

import numpy as np

from pushtrain import defaults
from pushtrain.errors import ControllerError
from pushtrain.settings import angle_setting, setting
from pushtrain.table1 import LINK
from pushtrain.validation import PositiveFloat

from .kinematics import ChainGeometry

__all__ = ["MODE_PULL", "MODE_PUSH", "MODE_REST", "ControlInfo", "ControllerConfig", "Gains"]

MODE_REST = "rest"
"""Reference at rest: zero command."""
MODE_PUSH = "push"
"""Last trailer leads: Kanayama on trailer n in its direction-of-travel frame + inverse map."""
MODE_PULL = "pull"
"""Robot leads: Kanayama on the robot along its own pulling reference (PullGuide)."""


@dataclass(frozen=True)
class ControllerConfig:
    """Gains, model and limits of the control law.

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
    k_x: float = setting(defaults.K_X, PositiveFloat)
    k_y: float = setting(defaults.K_Y, PositiveFloat)
    k_theta: float = setting(defaults.K_THETA, PositiveFloat)
    v_max: float = setting(defaults.V_MAX, PositiveFloat, part="robot")
    w_max: float = angle_setting(math.degrees(defaults.W_MAX), PositiveFloat, part="robot")
    acc_max: float | None = setting(defaults.ACC_MAX, PositiveFloat | None)
    alpha_max: float | None = angle_setting(defaults.ALPHA_MAX_DEG, PositiveFloat | None)
    rest_speed: float = defaults.REST_SPEED

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
    def uniform(cls, n_trailers: int, link: float = LINK, **kwargs) -> ControllerConfig:
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


class ControlInfo(NamedTuple):
    """Diagnostics of one command of the control law
    (:meth:`~pushtrain.core.native_controller.NativeController.command`).

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
