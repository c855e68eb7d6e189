"""The backward-motion controller on the compiled control law (``core/csrc/control.c``).

:class:`NativeController` (``command``, ``command_from``, ``reset``, ``sent``, ``n``,
``guide_geometry``) computes the command of :mod:`pushtrain.core.controller`'s scheme with the C
implementation that the fast closed-loop integrator (:mod:`pushtrain.core.engine`) and the
controller FMU compile: the product's one control law. ``tests/test_native_control.py`` holds
it equal to 1e-12 on random states, references and limit sequences, and the master's runs bit
for bit, to the readable Python reference ``BackwardController`` of
``tests/reference/controller.py``.

One difference, on purpose: the C law refuses every non-finite measured value and every
non-finite raw command with :class:`~pushtrain.errors.ControllerError`, where the Python
reference refuses a non-finite last-trailer pose or an infinite command only (and passes a NaN
command on).
"""

from __future__ import annotations

import ctypes
import struct
from functools import partial

import numpy as np

from pushtrain.errors import ControllerError, ReferencePathError

from . import native
from .controller import MODE_PULL, MODE_PUSH, MODE_REST, ControlInfo, ControllerConfig, Gains
from .native_reference import NativeReference
from .reference import Reference, ReferenceSample
from .tracking import TrackingLoop

__all__ = ["NativeController", "Tracker", "controller_struct"]

_MODES = {0: MODE_REST, 1: MODE_PUSH, 2: MODE_PULL}
_POSE = struct.Struct("@3d")  # PtMeasurement's x_n, y_n, theta_n
_TIME_POSE = struct.Struct("@4d")  # PtTrack's t, m.x0, m.y0, m.theta0
_SAMPLE_CMD = struct.Struct("@5di4x2d")  # PtTrack's sample and cmd
_INFO = struct.Struct("@i4x11d")  # PtControlInfo
_HAS_LAST = struct.Struct("@i")
_new_tuple = tuple.__new__


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


class NativeController:
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
        is neither a :class:`~pushtrain.core.reference.Reference` nor a
        :class:`~pushtrain.core.native_reference.NativeReference`.

        Returns a :class:`Tracker` whose ``command(t, measurement) -> (v0, w0, info, ref)`` is
        :meth:`TrackingLoop.command <pushtrain.core.tracking.TrackingLoop.command>` with this
        controller, ``reference`` and ``guide`` (the
        :class:`~pushtrain.core.pulling.PullGuide` of ``reference``, or None): the reference is
        copied into the C phase table; the guide is the C leader table already. With ``info``
        False ``command`` returns None in place of the ``ControlInfo``.
        """
        if isinstance(reference, Reference):
            reference = NativeReference.from_reference(reference)
        elif not isinstance(reference, NativeReference):
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
    """One control instant of :class:`NativeController` in C: reference sample, pull leader and
    command (``pt_track``), what :meth:`NativeController.tracker` returns.

    ``instant`` is the ``PtTrack`` struct the C reads and writes (a compiled loop may run it
    itself); ``has_last`` says whether it holds a measured last pose now."""

    def __init__(self, controller: NativeController, reference: NativeReference,
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
        self._offsets = (native.PtTrack.t.offset, native.PtTrack.sample.offset,
                         native.PtTrack.m.offset + native.PtMeasurement.has_last.offset,
                         native.PtTrack.m.offset + native.PtMeasurement.x_n.offset,
                         native.PtTrack.info.offset)
        self._call = partial(controller._lib.pt_track, ctypes.byref(k))
        self.has_last = False

    def command(self, t: float, measurement):
        """``(v0 [m/s], w0 [rad/s], ControlInfo or None, ReferenceSample)`` at ``t`` [s]."""
        try:
            self._phi[:] = measurement.phi
        except (ValueError, TypeError):
            self.controller._set_phi(measurement.phi)  # the controller's message on a bad length
            raise
        k = self.instant
        at_t, at_sample, at_has_last, at_last, at_info = self._offsets
        _TIME_POSE.pack_into(k, at_t, t, measurement.x0, measurement.y0, measurement.theta0)
        last = getattr(measurement, "last_pose", None)
        if last is not None:
            _HAS_LAST.pack_into(k, at_has_last, 1)
            _POSE.pack_into(k, at_last, *last)
        elif self.has_last:
            _HAS_LAST.pack_into(k, at_has_last, 0)
        self.has_last = last is not None
        status = self._call()
        out = _SAMPLE_CMD.unpack_from(k, at_sample)
        ref = _new_tuple(ReferenceSample, out[:6])
        if status:
            raise self.error(status, t, measurement, ref)
        if not self.info:
            return out[6], out[7], None, ref
        mode, *rest = _INFO.unpack_from(k, at_info)
        return out[6], out[7], ControlInfo(_MODES[mode], *rest), ref

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
