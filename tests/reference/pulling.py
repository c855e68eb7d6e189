"""The pull guide written in Python: the reference the engine's (``core/csrc/control.c``
``pt_pull_run``, ``pt_leader_sample``; :class:`pushtrain.core.pulling.PullGuide`) is held equal
to, bit for bit (``tests/core/test_native.py``).

For every pulling run [t_a, t_b] of the reference the chain starts drawn out straight at t_b and
is driven backward in time (RK4, ``reference.ode.rk4_step``) by the last trailer's
reference down to t_a; the robot's pose and velocity along the way are its reference.
"""

from __future__ import annotations

import math
from bisect import bisect_right

import numpy as np

from pushtrain.core.kinematics import (
    ChainGeometry,
    body_positions,
    robot_velocity_from_last,
)
from pushtrain.core.pulling import PullRun, rates_driven_by_last
from pushtrain.core.reference import ReferenceSample
from pushtrain.core.segment import PULL
from pushtrain.errors import ReferencePathError
from reference.ode import rk4_step


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
        x, y = body_positions(np.array([s.x for s in last]), np.array([s.y for s in last]),
                              headings, self.geometry, from_last=True)
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
