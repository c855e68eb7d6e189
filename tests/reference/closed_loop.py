"""The closed loop of the planner's train check in plain Python: the reference the compiled
engine (``core/csrc/rollout.c``, :mod:`pushtrain.core.engine`) is held equal to, bit for bit.

:func:`simulate_tracking` runs the reference law (``reference.controller.BackwardController``)
through :class:`~pushtrain.core.tracking.TrackingLoop` (reference sample, Python pull guide,
command) at the control instants ``t_k = k * step`` with a perfect measurement, holds each
command over the step and integrates the robot (along its heading) and the towed trailers with
RK4 (``reference.ode.rk4_step``) on ``z = (x0, y0, theta_0..theta_n)``: the loop
:func:`pushtrain.core.engine.simulate` runs in C. SI units, radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.kinematics import ChainGeometry, body_positions
from pushtrain.core.reference import Reference
from pushtrain.core.tracking import TrackingLoop
from pushtrain.defaults import ROLLOUT_SETTLE_TIME, ROLLOUT_STEP
from reference.controller import BackwardController
from reference.ode import rk4_step


@dataclass
class Trajectory:
    """The reference loop's run, one row per control instant k = 0..K: ``t`` (K+1,) [s],
    ``state`` (K+1, 3 + n), the ``command`` (v0, w0) computed there, the last trailer's
    ``reference`` pose and its ``direction``; ``control`` all True."""

    t: np.ndarray
    state: np.ndarray
    command: np.ndarray
    reference: np.ndarray
    direction: np.ndarray
    control: np.ndarray


def towed_rates(geometry: ChainGeometry):
    """``f(theta, v0, w0) -> list`` of the yaw rates d(theta_i)/dt [rad/s], i = 0..n, of a chain
    towed by the robot's (v0 [m/s], w0 [rad/s]) with headings ``theta`` (n+1,) [rad]: the
    recursion v_i = c v_{i-1} + R_{i-1} s w_{i-1}, w_i = (s v_{i-1} - R_{i-1} c w_{i-1}) / F_i
    with c, s of phi_i = theta_{i-1} - theta_i (``pt_towed_rates``)."""
    front = [float(a) for a in geometry.front]
    rear = [float(a) for a in geometry.rear]
    n = geometry.n

    def rates(theta, v0: float, w0: float, cos=math.cos, sin=math.sin):
        w = [0.0] * (n + 1)
        v, w[0] = v0, w0
        for i in range(1, n + 1):
            phi = theta[i - 1] - theta[i]
            c, s = cos(phi), sin(phi)
            r = rear[i - 1]
            v, w[i] = c * v + r * s * w[i - 1], (s * v - r * c * w[i - 1]) / front[i - 1]
        return w

    return rates


def rk4_hold(rates, state, v0: float, w0: float, h: float) -> list:
    """One RK4 step of (x0, y0, theta...) under the held robot command (v0, w0) (``pt_hold``)."""
    def f(_t, z):
        th = z[2:]
        return [v0 * math.cos(th[0]), v0 * math.sin(th[0])] + rates(th, v0, w0)

    return rk4_step(f, 0.0, state, h)


class PerfectMeasurement:
    """The measurement the loop hands the controller: robot pose and joint angles."""

    __slots__ = ("x0", "y0", "theta0", "phi")
    last_pose = None  # the last trailer's pose is estimated from the joints, as in the master

    def __init__(self, state):
        self.x0, self.y0, self.theta0 = state[0], state[1], state[2]
        th = state[2:]
        self.phi = [th[i - 1] - th[i] for i in range(1, len(th))]


def simulate_tracking(geometry: ChainGeometry, reference: Reference,
                      start_headings: Sequence[float], controller: ControllerConfig,
                      step: float = ROLLOUT_STEP,
                      settle_time: float = ROLLOUT_SETTLE_TIME) -> Trajectory:
    """The closed loop from t = 0 to the first instant at or after ``reference.t_end +
    settle_time``, the last trailer starting at ``reference.start`` with ``start_headings``, the
    robot at rest; every control instant one row."""
    ctrl = BackwardController(controller)
    ctrl.reset(0.0, 0.0, -step)
    loop = TrackingLoop(ctrl, reference)
    rates = towed_rates(geometry)
    th0 = np.asarray(start_headings, dtype=float)
    x0, y0, _ = reference.start
    x, y = body_positions(x0, y0, th0, geometry, from_last=True)
    state = [float(x[0]), float(y[0])] + [float(a) for a in th0]
    n_steps = int(math.ceil((reference.t_end + settle_time) / step - 1e-9))
    states, commands, refs, dirs = [], [], [], []
    for k in range(n_steps + 1):
        t = k * step
        v0, w0, _, ref = loop.command(t, PerfectMeasurement(state))
        states.append(state), commands.append((v0, w0))
        refs.append((ref.x, ref.y, ref.theta)), dirs.append(ref.direction)
        if k < n_steps:
            state = rk4_hold(rates, state, v0, w0, step)
    return Trajectory(step * np.arange(n_steps + 1), np.array(states), np.array(commands),
                      np.array(refs), np.array(dirs, dtype=int), np.ones(n_steps + 1, dtype=bool))
