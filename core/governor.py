"""Slip-aware speed governor: keep every trailer's lateral wheel force below friction.

The paper closes Sec. 4.4 with "control inputs can be modulated using online dynamic computations
in order to reduce F_d". The governor does that with the controller's *own* model of the train
(links, masses, inertias, friction) and of the robot's velocity loop, never with the plant's force
outputs:

1. It keeps an estimate of the robot's velocity (v0, w0) by running its model of the robot's
   velocity loop (first-order lag ``tau`` with rate limits) on the commands it lets through.
2. For a proposed command it predicts the robot's accelerations, then the chain's velocities and
   accelerations (differentiated no-slip map) and the lateral wheel forces by Newton-Euler from
   trailer n down (:func:`lateral_forces`, written here independently of the FMU's C code).
3. For the command ``previous + s (proposed - previous)`` it lets through the largest s in
   [0, 1] (bisection) that keeps every |F_i| <= ``fraction`` * mu_i (m_i + payload_i) g. Scaling
   the change keeps the direction of the command change; the tracking controller catches up.

If even s = 0 exceeds the limit (velocity-dependent forces alone are too large), the governor
holds the previous command and counts the event (``saturated``).
"""

from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass

import numpy as np

from pushtrain import defaults
from pushtrain.table1 import SAMPLING_TIME

from . import native
from .kinematics import ChainGeometry

__all__ = ["GovernorConfig", "SlipGovernor", "GovernedController", "lateral_forces"]


def lateral_forces(phi, v0, w0, dv0, dw0, geom: ChainGeometry, mass, inertia) -> np.ndarray:
    """Lateral wheel forces F_d,i [N] (i = 1..n) of rolling trailers.

    Parameters
    ----------
    phi : (n,) joint angles [rad]
    v0, w0 : robot speed [m/s] and yaw rate [rad/s]
    dv0, dw0 : robot accelerations [m/s^2, rad/s^2]
    geom : ChainGeometry
    mass, inertia : (n,) total masses [kg] (with payload) and yaw inertias about the axle [kg m^2]

    Each trailer's equations are written in its own frame (e_i, n_i); the hitch force of the next
    trailer is rotated by -phi_{i+1} into it.
    """
    n = geom.n
    c, s = np.cos(phi), np.sin(phi)
    v, w, dv, dw = [v0], [w0], [dv0], [dw0]
    for i in range(1, n + 1):
        r, f = geom.rear[i - 1], geom.front[i - 1]
        ci, si = c[i - 1], s[i - 1]
        vi = ci * v[-1] + r * si * w[-1]
        wi = (si * v[-1] - r * ci * w[-1]) / f
        phidot = w[-1] - wi
        dvi = -si * phidot * v[-1] + ci * dv[-1] + ci * phidot * r * w[-1] + si * r * dw[-1]
        dwi = (ci * phidot * v[-1] + si * dv[-1] + si * phidot * r * w[-1] - ci * r * dw[-1]) / f
        v.append(vi), w.append(wi), dv.append(dvi), dw.append(dwi)
    forces = np.empty(n)
    next_e = next_n = 0.0  # f_{i+1} in trailer i+1's frame
    for i in range(n, 0, -1):
        if i < n:  # rotate f_{i+1} from frame i+1 into frame i (angle -phi_{i+1})
            cp, sp = c[i], s[i]
            next_e, next_n = next_e * cp + next_n * sp, -next_e * sp + next_n * cp
        rear_link = geom.rear[i] if i < n else 0.0
        f_n = (inertia[i - 1] * dw[i] - rear_link * next_n) / geom.front[i - 1]
        f_e = mass[i - 1] * dv[i] + next_e
        forces[i - 1] = mass[i - 1] * v[i] * w[i] - f_n + next_n
        next_e, next_n = f_e, f_n
    return forces


@dataclass(frozen=True)
class GovernorConfig:
    """The governor's own model and margin.

    Parameters
    ----------
    geometry : ChainGeometry
    mass, inertia, mu : (n,) trailer masses with payload [kg], yaw inertias [kg m^2], friction [-]
    g : float
        Gravity [m/s^2].
    fraction : float
        Allowed share of the friction limit, in (0, 1].
    tau, acc_max, alpha_max : float
        The robot velocity loop as the governor models it: lag [s], rate limits [m/s^2, rad/s^2].
    """

    geometry: ChainGeometry
    mass: np.ndarray
    inertia: np.ndarray
    mu: np.ndarray
    g: float = defaults.GRAVITY
    fraction: float = defaults.GOVERNOR_FRACTION
    tau: float = defaults.ROBOT_TAU
    acc_max: float = defaults.ROBOT_ACC_MAX
    alpha_max: float = defaults.ROBOT_ALPHA_MAX

    def __post_init__(self):
        n = self.geometry.n
        for name in ("mass", "inertia", "mu"):
            arr = np.broadcast_to(np.asarray(getattr(self, name), dtype=float), (n,)).copy()
            if (not np.all(np.isfinite(arr)) or np.any(arr < 0)
                    or (name != "mu" and np.any(arr <= 0))):
                raise ValueError(f"governor {name} = {arr.tolist()}: must be finite and > 0")
            object.__setattr__(self, name, arr)
        if not (0.0 < self.fraction <= 1.0):
            raise ValueError(f"governor fraction = {self.fraction!r}: allowed is (0, 1]")
        for name in ("tau", "acc_max", "alpha_max", "g"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"governor {name} = {value!r}: must be finite and > 0")

    @property
    def limits(self) -> np.ndarray:
        """Allowed |F_d,i| [N]: fraction * mu_i m_i g."""
        return self.fraction * self.mu * self.mass * self.g


class SlipGovernor:
    """Limits command changes so that the predicted lateral forces stay within friction.

    The engine's governor (``core/csrc/governor.c``, ``pt_governor_limit``) with its memory in
    :attr:`struct`: the co-simulation's step loop runs it in C after the compiled law; this is
    its Python face. The readable Python form is the tests' (``tests/reference/governor.py``),
    held equal bit for bit."""

    def __init__(self, config: GovernorConfig):
        self.config = config
        self._lib = native.load()
        geometry = config.geometry
        self._arrays = [np.ascontiguousarray(a, dtype=float) for a in (
            geometry.front, geometry.rear, config.mass, config.inertia, config.limits)]
        front, rear, mass, inertia, limits = (native.dptr(a) for a in self._arrays)
        self.struct = native.PtGovernor(
            native.PtChain(geometry.n, front, rear), mass, inertia, limits, float(config.tau),
            float(config.acc_max), float(config.alpha_max), 0.0)
        self.work = np.zeros(self._lib.pt_governor_work(geometry.n))
        self._v, self._w = ctypes.c_double(), ctypes.c_double()
        self.reset()

    def reset(self, v0: float = 0.0, w0: float = 0.0) -> None:
        """Forget the history: the robot moves and was commanded with (v0, w0) [m/s, rad/s]."""
        g = self.struct
        g.v_est, g.w_est = float(v0), float(w0)
        g.v_prev, g.w_prev = float(v0), float(w0)
        g.saturated = g.limited = 0

    @property
    def saturated(self) -> int:
        """Commands held because even no change exceeded the limit."""
        return int(self.struct.saturated)

    @property
    def limited(self) -> int:
        """Commands changed less than the law asked."""
        return int(self.struct.limited)

    @property
    def estimate(self) -> tuple[float, float]:
        """The governor's estimate of the robot's (v0 [m/s], w0 [rad/s])."""
        return float(self.struct.v_est), float(self.struct.w_est)

    def limit(self, phi, v_cmd: float, w_cmd: float, dt: float):
        """The command to send instead of (v_cmd, w_cmd) given measured joint angles ``phi``.

        ``dt`` [s] is the control period over which the robot-velocity estimate advances.
        """
        self.struct.dt = float(dt)
        angles = np.ascontiguousarray(phi, dtype=float)
        self._v.value, self._w.value = v_cmd, w_cmd
        self._lib.pt_governor_limit(ctypes.byref(self.struct), native.dptr(angles),
                                    ctypes.byref(self._v), ctypes.byref(self._w),
                                    native.dptr(self.work))
        return self._v.value, self._w.value


class GovernedController:
    """A tracking controller whose commands pass through a :class:`SlipGovernor`.

    Has the interface the co-simulation master expects (``n``, ``guide_geometry``, ``reset``,
    ``command``).
    """

    def __init__(self, controller, governor: SlipGovernor, dt: float = SAMPLING_TIME):
        self.controller = controller
        self.governor = governor
        self.dt = dt
        self.n = controller.n
        self.guide_geometry = controller.guide_geometry

    def reset(self, v0: float = 0.0, w0: float = 0.0, t=None) -> None:
        self.controller.reset(v0, w0, t)
        self.governor.reset(v0, w0)

    def tracker(self, reference, guide=None, info: bool = True):
        """The compiled law's one-call instant with this governor after it (the co-simulation's
        step loop runs both in C), or None if the law is not the compiled one."""
        make = getattr(self.controller, "tracker", None)
        tracker = None if make is None else make(reference, guide, info)
        if tracker is not None:
            tracker.governor, tracker.dt = self.governor, self.dt
        return tracker

    def command(self, t, measurement, ref, leader=None):
        v, w, info = self.controller.command(t, measurement, ref, leader)
        v_out, w_out = self.governor.limit(measurement.phi, v, w, self.dt)
        if (v_out, w_out) != (v, w):
            self.controller.sent(v_out, w_out)  # its rate limits continue from what was sent
        return v_out, w_out, info
