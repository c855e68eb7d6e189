"""Backward-motion control law of a robot with n off-hooked trailers (Steps 2-3 of the paper):
its settings (:class:`ControllerConfig`), gains, modes and diagnostics (:class:`ControlInfo`).

The law is computed in C (``core/csrc/control.c``): by
:class:`~pushtrain.core.controller.Controller` in the co-simulation, by the
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

import ctypes
import math
from dataclasses import dataclass
from functools import partial
from math import isfinite
from typing import NamedTuple

import numpy as np

from pushtrain import defaults
from pushtrain.errors import ControllerError, ReferencePathError
from pushtrain.settings import angle_setting, setting
from pushtrain.table1 import LINK
from pushtrain.validation import PositiveFloat

from . import native
from .kinematics import ChainGeometry
from .reference import Reference, ReferenceSample
from .tracking import TrackingLoop

__all__ = ["MODE_PULL", "MODE_PUSH", "MODE_REST", "ControlInfo", "Controller", "ControllerConfig",
           "Gains", "Tracker", "controller_struct"]

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
    (:meth:`~pushtrain.core.controller.Controller.command`).

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


_MODES = {0: MODE_REST, 1: MODE_PUSH, 2: MODE_PULL}


def controller_struct(config: ControllerConfig, lib=None):
    """The C ``PtController`` of ``config`` and the arrays it points to (keep both alive).

    Returns ``(struct, (front, rear))``.
    """
    front = np.ascontiguousarray(config.geometry.front, dtype=float).copy()
    rear = np.ascontiguousarray(config.geometry.rear, dtype=float).copy()
    struct = native.PtController(
        native.PtChain(config.geometry.n, native.dptr(front), native.dptr(rear)),
        float(config.k_x), float(config.k_y), float(config.k_theta),
        float(config.v_max), float(config.w_max),
        0.0 if config.acc_max is None else float(config.acc_max),
        0.0 if config.alpha_max is None else float(config.alpha_max),
        float(config.rest_speed))
    return struct, (front, rear)


class Controller:
    """Backward-motion controller computed by the C control law.

    Parameters
    ----------
    config : ControllerConfig

    Raises
    ------
    ControllerError
        A bad ``config``.
    NativeBuildError
        The C library cannot be built or loaded.
    """

    def __init__(self, config: ControllerConfig):
        if not isinstance(config, ControllerConfig):
            raise ControllerError(f"config = {config!r}: must be a ControllerConfig")
        self.config = config
        self.n = config.geometry.n
        self.gains = Gains(float(config.k_x), float(config.k_y), float(config.k_theta))
        self.guide_geometry = config.geometry
        self._lib = native.load()
        self._ctrl, self._arrays = controller_struct(config)
        self._state = native.PtControlState()
        self._phi = np.zeros(self.n)
        self._meas = native.PtMeasurement()
        self._meas.phi = native.dptr(self._phi)
        self._ref = native.PtSample()
        self._leader = native.PtSample()
        self._cmd = np.zeros(2)
        self._cmd_ptr = native.dptr(self._cmd)
        self._pose = np.zeros(3)
        self._info = native.PtControlInfo()
        self._args = tuple(ctypes.byref(a) for a in (self._ctrl, self._state, self._meas,
                                                     self._ref, self._leader, self._info))
        self._loop: TrackingLoop | None = None
        self.reset()

    def reset(self, v0: float = 0.0, w0: float = 0.0, t: float | None = None) -> None:
        """Forget the history: the previous command becomes ``(v0, w0)`` [m/s, rad/s] at ``t``
        [s] (None: the next command is not rate limited)."""
        self._lib.pt_control_reset(self._args[1], float(v0), float(w0),
                                   0.0 if t is None else float(t), 0 if t is None else 1)

    def sent(self, v0: float, w0: float) -> None:
        """Record the command actually sent after an outer limiter (the rate limits continue
        from it)."""
        self._lib.pt_control_sent(self._args[1], float(v0), float(w0))

    @property
    def state(self) -> tuple:
        """The rate limits' memory ``(v_prev [m/s], w_prev [rad/s], t_prev [s] or None)``."""
        s = self._state
        return s.v_prev, s.w_prev, (s.t_prev if s.has_t_prev else None)

    def last_trailer_pose(self, x0: float, y0: float, theta0: float, phi) -> tuple:
        """Pose (x_n, y_n, theta_n) [m, m, rad] of trailer n from the robot pose and joints."""
        self._set_phi(phi)
        self._lib.pt_last_trailer_pose(ctypes.byref(self._ctrl.model), float(x0), float(y0),
                                       float(theta0), native.dptr(self._phi),
                                       native.dptr(self._pose))
        return tuple(float(a) for a in self._pose)

    def robot_velocity(self, phi, v_n: float, w_n: float) -> tuple:
        """Robot (v0 [m/s], w0 [rad/s]) making trailer n move with (v_n, w_n) (Eq. 5)."""
        self._set_phi(phi)
        self._lib.pt_robot_velocity_from_last(ctypes.byref(self._ctrl.model),
                                              native.dptr(self._phi), float(v_n), float(w_n),
                                              self._cmd_ptr)
        return float(self._cmd[0]), float(self._cmd[1])

    def _set_phi(self, phi) -> None:
        if len(phi) != self.n:
            raise ControllerError(
                f"measurement.phi has {len(phi)} joint angles; the controller's chain has {self.n}"
            )
        self._phi[:] = phi

    def command(self, t: float, measurement, ref, leader=None):
        """Robot command ``(v0 [m/s], w0 [rad/s], ControlInfo)`` at time ``t`` [s].

        ``measurement`` has ``x0, y0, theta0`` (measured robot pose [m, m, rad]), ``phi`` (the
        n measured joint angles [rad]) and optionally ``last_pose`` (a direct measurement of the
        last trailer's pose, used in place of the estimate from the joints when not None);
        ``ref`` is the last trailer's :class:`~pushtrain.core.reference.ReferenceSample` at
        ``t``, ``leader`` the robot's own (pull guide) sample, needed only while pulling.

        Raises
        ------
        ControllerError
            A wrong number of joint angles, a non-finite measurement or command, pulling
            without ``leader``, or an unknown ``ref.direction``.
        """
        self._set_phi(measurement.phi)
        m = self._meas
        m.x0, m.y0, m.theta0 = measurement.x0, measurement.y0, measurement.theta0
        last = getattr(measurement, "last_pose", None)
        if last is None:
            m.has_last = 0
        else:
            m.has_last = 1
            m.x_n, m.y_n, m.theta_n = last
        r = self._ref
        r.x, r.y, r.theta, r.v, r.w, r.direction = (ref.x, ref.y, ref.theta, ref.v, ref.w,
                                                    int(ref.direction))
        if leader is not None:
            g = self._leader
            g.x, g.y, g.theta, g.v, g.w, g.direction = (leader.x, leader.y, leader.theta,
                                                        leader.v, leader.w, int(leader.direction))
        ctrl, state, meas, ref_p, leader_p, info_p = self._args
        status = self._lib.pt_command(ctrl, state, float(t), meas, ref_p,
                                      leader_p if leader is not None else None, self._cmd_ptr,
                                      info_p)
        if status:
            raise self._error(status, t, measurement, ref)
        i = self._info
        info = ControlInfo(_MODES[i.mode], i.x_e, i.y_e, i.theta_e, i.x_n, i.y_n, i.theta_n,
                           i.v_ref, i.w_ref, i.v_raw, i.w_raw, i.scale)
        return float(self._cmd[0]), float(self._cmd[1]), info

    def _error(self, status: int, t, measurement, ref) -> ControllerError:
        if status == 1:
            return ControllerError(
                f"non-finite measurement at t = {t!r} s: robot pose ({measurement.x0!r}, "
                f"{measurement.y0!r}, {measurement.theta0!r}), phi = {list(measurement.phi)!r}, "
                f"last_pose = {getattr(measurement, 'last_pose', None)!r}; all must be finite")
        if status == 2:
            i = self._info
            return ControllerError(f"non-finite command ({i.v_raw!r}, {i.w_raw!r}) at "
                                   f"t = {t!r} s")
        if status == 3:
            return ControllerError(
                f"pulling at t = {t!r} s needs the robot's reference `leader` "
                "(PullGuide(reference, controller.guide_geometry).sample_at(t));"
                " use command_from(reference, t, measurement)")
        if status == 4:
            return ControllerError(
                f"ref.direction = {ref.direction!r}: allowed are +1 (push), -1 (pull), 0 (rest)")
        return ControllerError(f"control law failed at t = {t!r} s: "
                               f"{native.STATUS.get(status, status)}")

    def tracker(self, reference, guide=None, info: bool = True):
        """The whole control instant in one C call (``pt_track``), or None if ``reference``
        is not a line/arc :class:`~pushtrain.core.reference.Reference` (a sampled one).

        Returns a :class:`Tracker` whose ``command(t, measurement) -> (v0, w0, info, ref)`` is
        :meth:`TrackingLoop.command <pushtrain.core.tracking.TrackingLoop.command>` with this
        controller, ``reference`` and ``guide`` (the
        :class:`~pushtrain.core.pulling.PullGuide` of ``reference``, or None): both are C
        tables already. With ``info``
        False ``command`` returns None in place of the ``ControlInfo``.
        """
        if not isinstance(reference, Reference):
            return None
        return Tracker(self, reference, guide, info)

    def command_from(self, reference, t: float, measurement):
        """:meth:`command` with ``ref`` and ``leader`` taken from ``reference`` at ``t`` [s],
        through a :class:`~pushtrain.core.tracking.TrackingLoop` of this controller kept while
        the calls pass the same reference object."""
        if self._loop is None or self._loop.reference is not reference:
            self._loop = TrackingLoop(self, reference)
        return self._loop.command(t, measurement)[:3]


class Tracker:
    """One control instant of :class:`Controller` in C: reference sample, pull leader and
    command (``pt_track``), what :meth:`Controller.tracker` returns.

    ``instant`` is the ``PtTrack`` struct the C reads and writes (a compiled loop may run it
    itself); ``has_last`` says whether it holds a measured last pose now."""

    def __init__(self, controller: Controller, reference: Reference,
                 leader, info: bool = True):
        self.controller, self.reference, self.leader = controller, reference, leader
        self.info = info
        n = controller.n
        self._phi = (ctypes.c_double * n)()
        ctrl, state = controller._ctrl, controller._state
        k = self.instant = native.PtTrack(
            ctypes.pointer(ctrl), ctypes.pointer(state), ctypes.pointer(reference.struct),
            None if leader is None else ctypes.pointer(leader.struct))
        k.m.phi = ctypes.cast(self._phi, native.D_PTR)
        self._call = partial(controller._lib.pt_track, ctypes.byref(k))
        self.has_last = False
        self.governor = None
        """A :class:`~pushtrain.core.governor.SlipGovernor` applied to each command, or None
        (set by :meth:`GovernedController.tracker
        <pushtrain.core.governor.GovernedController.tracker>`, with its period ``dt``)."""
        self.dt = 0.0

    def command(self, t: float, measurement):
        """``(v0 [m/s], w0 [rad/s], ControlInfo or None, ReferenceSample)`` at ``t`` [s]."""
        try:
            self._phi[:] = measurement.phi
        except (ValueError, TypeError):
            self.controller._set_phi(measurement.phi)  # the controller's message on a bad length
            raise
        k = self.instant
        k.t = t
        m = k.m
        m.x0, m.y0, m.theta0 = measurement.x0, measurement.y0, measurement.theta0
        last = getattr(measurement, "last_pose", None)
        m.has_last = last is not None
        if last is not None:
            m.x_n, m.y_n, m.theta_n = last
        self.has_last = last is not None
        status = self._call()
        s = k.sample
        ref = ReferenceSample(s.x, s.y, s.theta, s.v, s.w, s.direction)
        if status:
            raise self.error(status, t, measurement, ref)
        v0, w0 = k.cmd
        if self.governor is not None:
            v, w = self.governor.limit(measurement.phi, v0, w0, self.dt)
            if (v, w) != (v0, w0):
                self.controller.sent(v, w)  # its rate limits continue from what was sent
            v0, w0 = v, w
        if not self.info:
            return v0, w0, None, ref
        i = k.info
        return v0, w0, ControlInfo(_MODES[i.mode], i.x_e, i.y_e, i.theta_e, i.x_n, i.y_n,
                                   i.theta_n, i.v_ref, i.w_ref, i.v_raw, i.w_raw, i.scale), ref

    def error(self, status: int, t, measurement, ref) -> Exception:
        """The exception of a control instant the C refused with ``status`` at ``t`` [s] for
        ``measurement`` (its reference sample ``ref``)."""
        if status == 2:  # the controller's message reads the raw command from its own info
            ctypes.memmove(ctypes.byref(self.controller._info), ctypes.byref(self.instant.info),
                           ctypes.sizeof(native.PtControlInfo))
        if status == 8:
            return ReferencePathError(f"t = {t!r} s is not in a pulling run of the reference")
        if status == 9:
            return ReferencePathError(f"sampling the reference at t = {t!r} s: "
                                      f"{native.STATUS[status]}")
        return self.controller._error(status, t, measurement, ref)
