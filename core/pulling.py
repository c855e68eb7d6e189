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

import ctypes
import math
from dataclasses import dataclass

import numpy as np

from pushtrain.defaults import PULL_GUIDE_STEP
from pushtrain.errors import ReferencePathError

from . import native
from .kinematics import ChainGeometry, body_positions, velocities_from_last
from .reference import Reference, ReferenceSample
from .segment import PULL

__all__ = ["PullGuide", "PullRun", "rates_driven_by_last", "straight_chain_mismatch"]

_COLUMNS = ("t", "x", "y", "theta", "v", "w")  # of a PullRun and the C leader table
_SAMPLER = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double,
                            ctypes.POINTER(native.PtSample))  # control.h PtSampler


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
    x, y = body_positions(0.0, 0.0, np.array([theta, target]), geometry, from_last=True)
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
    """The robot's reference for every pulling run of a last-trailer reference, computed and
    sampled by the engine (``pt_pull_run``, ``pt_leader_sample`` in ``core/csrc/control.c``):
    the one pull guide of the co-simulation, the planner's rollouts and the controller FMU's
    table. The readable Python form is the tests' reference (``tests/reference/pulling.py``),
    held equal bit for bit.

    Parameters
    ----------
    reference : Reference or SampledReference
        The last trailer's reference: a line/arc one is sampled in C; any other with
        ``pull_intervals()`` and ``sample_at(t)`` is sampled through a callback.
    geometry : ChainGeometry
        The chain model (the controller's).
    step : float
        Integration step [s] of the backward run (RK4), > 0 (shorter runs take one step). The
        default (:data:`pushtrain.defaults.PULL_GUIDE_STEP`, 0.02 s) is 1.6 mm of travel at
        0.08 m/s; the guide's error is far below the tracking errors.

    Attributes
    ----------
    runs : list of PullRun
        One per pulling run, in time order.
    struct : pushtrain.core.native.PtLeader
        The C table of the runs (the arrays behind it stay alive with this object).

    Raises
    ------
    ReferencePathError
        For a bad ``geometry`` or ``step``. A reference that turns too sharply for a pull is
        not refused here: the guide's joint angles (:attr:`PullRun.headings`) then exceed what
        the chain allows, and the closed loop shows the consequences.
    """

    def __init__(self, reference, geometry: ChainGeometry, step: float = PULL_GUIDE_STEP):
        if not isinstance(geometry, ChainGeometry):
            raise ReferencePathError(f"geometry = {geometry!r}: must be a ChainGeometry")
        if not (isinstance(step, (int, float)) and math.isfinite(step) and step > 0.0):
            raise ReferencePathError(f"step = {step!r} s: must be finite and > 0")
        self.reference = reference
        self.geometry = geometry
        self.step = float(step)
        self._lib = native.load()
        self.runs: list[PullRun] = [self._backward_run(a, b)
                                    for a, b in reference.pull_intervals()]
        offsets = np.cumsum([0] + [len(run.t) for run in self.runs]).astype(np.intc)
        self._offset = np.ascontiguousarray(offsets)
        self._cols = {name: np.ascontiguousarray(
            np.concatenate([getattr(run, name) for run in self.runs]) if self.runs
            else np.zeros(0), dtype=float) for name in _COLUMNS}
        self.struct = native.PtLeader(
            len(self.runs), self._offset.ctypes.data_as(ctypes.POINTER(ctypes.c_int)),
            *(native.dptr(self._cols[name]) for name in _COLUMNS))
        self._sample = native.PtSample()

    # -------------------------------------------------------------------- the backward run
    def _sampler(self):
        """``(function, source)`` of ``pt_pull_run_sampled`` for the reference, and what must
        stay alive through the call."""
        reference = self.reference
        if isinstance(reference, Reference):
            address = ctypes.cast(self._lib.pt_reference_sample, ctypes.c_void_p).value
            return address, ctypes.addressof(reference.struct), reference

        def sample(_source, t: float, out) -> int:
            try:
                s = self.reference.sample_at(t)
            except Exception:  # noqa: BLE001 (the backward run reads a status)
                return 5
            o = out.contents
            o.x, o.y, o.theta, o.v, o.w, o.direction = (s.x, s.y, s.theta, s.v, s.w,
                                                        int(s.direction))
            return 0

        callback = _SAMPLER(sample)
        return ctypes.cast(callback, ctypes.c_void_p).value, None, callback

    def _backward_run(self, t_a: float, t_b: float) -> PullRun:
        geometry, step = self.geometry, self.step
        rows = self._lib.pt_pull_run_rows(t_a, t_b, step)
        if rows < 2:
            raise ReferencePathError(f"pulling run [{t_a!r}, {t_b!r}] s with step {step!r} s: "
                                     "cannot be sampled")
        front = np.ascontiguousarray(geometry.front, dtype=float)
        rear = np.ascontiguousarray(geometry.rear, dtype=float)
        chain = native.PtChain(geometry.n, native.dptr(front), native.dptr(rear))
        work = np.zeros(self._lib.pt_pull_run_work(geometry.n))
        cols = [np.zeros(rows) for _ in _COLUMNS]
        headings = np.zeros((rows, geometry.n + 1))
        function, source, _alive = self._sampler()
        status = self._lib.pt_pull_run_sampled(
            ctypes.byref(chain), function, source, t_a, t_b, step, native.dptr(work),
            *(native.dptr(c) for c in cols), native.dptr(headings))
        if status:
            raise ReferencePathError(f"pull guide over [{t_a!r}, {t_b!r}] s: "
                                     f"{native.STATUS.get(status, status)}")
        return PullRun(*cols, headings)

    # -------------------------------------------------------------------- sampling
    def sample_at(self, t: float) -> ReferenceSample:
        """The robot's reference ``(x0, y0, theta0, v0, w0, PULL)`` at time ``t`` [s].

        ``t`` must lie in a pulling run (times a hair outside are clamped to the nearest run);
        linear interpolation between the backward run's samples.
        """
        status = self._lib.pt_leader_sample(ctypes.byref(self.struct), float(t),
                                            ctypes.byref(self._sample))
        if status:
            raise ReferencePathError(f"t = {t!r} s is not in a pulling run of the reference")
        s = self._sample
        return ReferenceSample(s.x, s.y, s.theta, s.v, s.w, PULL)
