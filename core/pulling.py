"""The robot's reference while pulling, computed backward in time from the end of each pull.

While the robot pulls (direction PULL) the last trailer cannot be steered through the inverse map:
prescribing it while it moves toward the robot makes the joints unstable (see
:mod:`pushtrain.core.controller`). The robot therefore leads, and it needs a reference of its
own that makes the towed chain bring the last trailer along the last trailer's reference.

Time reversal gives that reference exactly. Run backward in time, a pull is a push: the last
trailer moves away from the robot, and the chain's headings under the inverse map (Step 3,
``heading_rates_from_last``) are then stable. So for every pulling run [t_a, t_b] of the
reference, :class:`PullGuide` starts at the run's end t_b with the chain drawn out *straight*
ahead of the last trailer (where pushing after a cusp starts best, and what the planner checks:
``PlannerConfig.straight_pull_ends``), moves the last trailer backward along its reference to
t_a, and records where the robot is and how it moves: ``(x0, y0, theta0, v0, w0)`` at every
time. Forward in time the robot tracking this (Kanayama in its forward frame) tows the trailers
along their own reference, and any error of the towed chain decays (towing is stable).

What the guide cannot choose is the chain's configuration at the start of the pull: that is
whatever the previous motion left. The backward run forgets its straight end within a few chain
lengths, so on pulls longer than that the guide's start configuration is the one the reference's
shape near t_a calls for; the difference from the actual chain is a transient the robot's
tracking and the chain's own stability remove.

Units: SI, angles in radians, chain conventions of :mod:`pushtrain.core.kinematics`.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass

import numpy as np

from pushtrain.errors import ReferencePathError

from .kinematics import (
    ChainGeometry,
    body_positions_along,
    robot_velocity_from_last,
    velocities_from_last,
)
from .ode import rk4_step
from .reference import PULL, ReferenceSample

__all__ = ["PullGuide", "PullRun", "rates_driven_by_last", "straight_chain_mismatch"]


def rates_driven_by_last(geometry: ChainGeometry):
    """A fast scalar form of :func:`~pushtrain.core.kinematics.heading_rates_from_last`.

    Returns ``f(theta, v_n, w_n) -> list`` of d(theta_i)/dt [rad/s], i = 0..n, when the last
    trailer moves with (v_n [m/s], w_n [rad/s]) and the headings are ``theta`` (n+1,) [rad]
    (Step 3, Eq. 5 for general links). With v_n = 1 the rates are per metre travelled.
    """
    front = [float(a) for a in geometry.front]
    rear = [float(a) for a in geometry.rear]
    n = geometry.n

    def rates(theta, v_n: float, w_n: float) -> list[float]:
        phi = [theta[i] - theta[i + 1] for i in range(n)]
        return velocities_from_last(phi, v_n, w_n, front, rear)[1]

    return rates


def straight_chain_mismatch(geometry: ChainGeometry, path, target_headings=None) -> float:
    """How far a pull along ``path`` starts from the chain it needs, drawn back from a straight end.

    ``path`` is the last trailer's pulled path as poses (x, y, theta) [m, m, rad], (K, 3), in
    travel order, theta continuous or wrapped (chain convention: theta toward the robot, so
    pulling moves along +theta). The chain is drawn out straight at ``path[-1]`` and driven
    back along the path (the stable direction; the midpoint rule per sample interval with the
    interval's mean curvature, error second order in the spacing); returned is the largest
    distance [m] between a body there and the same body of the chain with ``target_headings``
    (n+1,) at ``path[0]`` (None: straight). Zero means the pull can be followed exactly from
    that chain; see :class:`PullGuide`.
    """
    pts = np.asarray(path, dtype=float)
    rates = rates_driven_by_last(geometry)
    th_last = np.unwrap(pts[:, 2])
    n = geometry.n
    theta = [float(th_last[-1])] * (n + 1)
    for j in range(pts.shape[0] - 1, 0, -1):
        ds = math.hypot(pts[j, 0] - pts[j - 1, 0], pts[j, 1] - pts[j - 1, 1])
        if ds <= 0.0:
            continue
        w = (th_last[j] - th_last[j - 1]) / ds
        h = -ds
        k1 = rates(theta, 1.0, w)  # the midpoint rule: second order, a check needs no more
        k2 = rates([a + 0.5 * h * b for a, b in zip(theta, k1, strict=True)], 1.0, w)
        theta = [a + h * b for a, b in zip(theta, k2, strict=True)]
        theta[-1] = float(th_last[j - 1])
    target = (np.full(n + 1, th_last[0]) if target_headings is None
              else np.asarray(target_headings, dtype=float))
    # both chains with the last trailer at the origin
    x, y = body_positions_along(np.zeros((2, 3)), np.array([theta, target]), geometry)
    return float(np.hypot(x[0] - x[1], y[0] - y[1]).max())


@dataclass(frozen=True)
class PullRun:
    """The robot's reference over one pulling run (arrays of equal length, times ascending).

    Attributes
    ----------
    t : (K,) array
        Times [s] from the run's start ``t[0]`` to its end ``t[-1]``.
    x, y, theta : (K,) arrays
        Robot pose [m, m, rad] (theta continuous).
    v, w : (K,) arrays
        Robot speed [m/s] (> 0 when pulling) and yaw rate [rad/s].
    headings : (K, n+1) array
        Headings of robot and trailers [rad] (the last column is the reference's theta).
    """

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    v: np.ndarray
    w: np.ndarray
    headings: np.ndarray


class PullGuide:
    """The robot's reference for every pulling run of a last-trailer reference.

    Parameters
    ----------
    reference : Reference or SampledReference
        Anything with ``pull_intervals()`` (start and end times of the pulling runs) and
        ``sample_at(t)``.
    geometry : ChainGeometry
        The chain model (the controller's).
    step : float
        Integration step [s] of the backward run (RK4), > 0 (shorter runs take one step). The
        default 0.02 s is 1.6 mm of
        travel at 0.08 m/s; the guide's error is far below the tracking errors.

    Raises
    ------
    ReferencePathError
        For a bad ``geometry`` or ``step``. A reference that turns too sharply for a pull is
        not refused here: the guide's joint angles (:attr:`PullRun.headings`) then exceed what
        the chain allows, and the closed loop shows the consequences.
    """

    def __init__(self, reference, geometry: ChainGeometry, step: float = 0.02):
        if not isinstance(geometry, ChainGeometry):
            raise ReferencePathError(f"geometry = {geometry!r}: must be a ChainGeometry")
        if not (isinstance(step, (int, float)) and math.isfinite(step) and step > 0.0):
            raise ReferencePathError(f"step = {step!r} s: must be finite and > 0")
        self.reference = reference
        self.geometry = geometry
        self.step = float(step)
        self._front = [float(a) for a in geometry.front]
        self._rear = [float(a) for a in geometry.rear]
        self._driven = rates_driven_by_last(geometry)
        self.runs: list[PullRun] = [self._backward_run(a, b)
                                    for a, b in reference.pull_intervals()]
        self._starts = [run.t[0] for run in self.runs]

    # -------------------------------------------------------------------- the backward run
    def _backward_run(self, t_a: float, t_b: float) -> PullRun:
        ref = self.reference
        eps = 1e-9 * max(1.0, abs(t_b))

        def vw(t: float) -> tuple[float, float]:
            s = ref.sample_at(min(max(t, t_a), t_b - eps))
            return s.v, s.w

        k_steps = max(1, int(math.ceil((t_b - t_a) / self.step)))
        times = np.linspace(t_b, t_a, k_steps + 1)  # descending
        n = self.geometry.n
        end = ref.sample_at(t_b - eps)
        theta = [float(end.theta)] * (n + 1)  # drawn out straight at the run's end
        rows = [theta]

        last = [math.nan, None]  # RK4 asks twice for the midpoint: sample it once

        def rates(t: float, theta: list) -> list:
            if t != last[0]:
                last[0], last[1] = t, vw(t)
            return self._driven(theta, *last[1])

        for k in range(k_steps):
            t, h = times[k], times[k + 1] - times[k]  # h < 0
            theta = rk4_step(rates, t, theta, h)
            theta[-1] = float(ref.sample_at(min(max(times[k + 1], t_a), t_b - eps)).theta)
            rows.append(theta)
        rows.reverse()
        times = times[::-1].copy()
        headings = np.array(rows)
        last = [ref.sample_at(min(max(t, t_a), t_b - eps)) for t in times]
        x, y = body_positions_along(np.array([(s.x, s.y, s.theta) for s in last]), headings,
                                    self.geometry)
        velocities = np.array([
            robot_velocity_from_last([th[i - 1] - th[i] for i in range(1, n + 1)], s.v, s.w,
                                     self._front, self._rear)
            for th, s in zip(rows, last, strict=True)
        ])
        return PullRun(times, x[:, 0].copy(), y[:, 0].copy(), headings[:, 0].copy(),
                       velocities[:, 0].copy(), velocities[:, 1].copy(), headings)

    # -------------------------------------------------------------------- sampling
    def sample_at(self, t: float) -> ReferenceSample:
        """The robot's reference ``(x0, y0, theta0, v0, w0, PULL)`` at time ``t`` [s].

        ``t`` must lie in a pulling run (times a hair outside are clamped to the nearest run);
        linear interpolation between the backward run's samples.
        """
        t = float(t)
        run = None
        if self.runs:
            j = max(bisect_right(self._starts, t) - 1, 0)
            if j + 1 < len(self.runs) and t - self.runs[j].t[-1] > self.runs[j + 1].t[0] - t:
                j += 1
            if self.runs[j].t[0] - 1e-6 <= t <= self.runs[j].t[-1] + 1e-6:
                run = self.runs[j]
        if run is None:
            raise ReferencePathError(f"t = {t!r} s is not in a pulling run of the reference")
        ts = run.t
        tc = min(max(t, ts[0]), ts[-1])
        k = min(max(int(np.searchsorted(ts, tc, side="right")) - 1, 0), ts.size - 2)
        a = (tc - ts[k]) / (ts[k + 1] - ts[k]) if ts[k + 1] > ts[k] else 0.0
        vals = [(1.0 - a) * c[k] + a * c[k + 1] for c in (run.x, run.y, run.theta, run.v, run.w)]
        return ReferenceSample(*[float(v) for v in vals], PULL)
