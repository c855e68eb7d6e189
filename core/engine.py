"""The closed-loop engine: the control law in closed loop with the kinematic chain, in C.

:class:`ClosedLoopEngine` runs the reference sampled at the control instants
``t_k = t_start + k step``, the robot's own reference from the pull guide while pulling, the
controller's command held over the step, the robot moving along its heading, the trailers towed,
RK4 over the step on ``(x0, y0, theta_0..theta_n)``, in ``core/csrc/rollout.c`` on top of the
compiled control law. It is the planner's only closed loop: its search
(:class:`pushtrain.planner.propagate.Propagator`, on :class:`LoopState` and :class:`EngineRun`)
and its final check (:func:`simulate`, checked by
:func:`pushtrain.planner.train_check.check_train`) both run it. The readable Python loop it is
held equal to, bit for bit, is the tests' reference (``tests/reference/closed_loop.py``).
:meth:`ClosedLoopEngine.hold` is its integrator alone (samples between two control instants).

Resumable
    A run returns its end :class:`LoopState` (instant index k, state, the controller's rate-limit
    memory); the next run continues from it. Running instants [k0, k1) and then [k1, k2) gives
    the states of one run over [k0, k2) bit for bit (:func:`join_runs` makes the pieces one
    :class:`EngineRun`). The command at the end instant is left to the next run, so that run
    may use a reference extended meanwhile.

Edges of a planner
    A planner's edge appends segments after the reference so far and continues the train's
    state. Either extend a copy of the reference (:meth:`Reference.copy`, ``extend``) or
    start a :meth:`Reference.continuation` at its end: at or after the end time of the
    reference so far both sample exactly as the whole reference. Run an edge up to
    ``loop.instant_at(edge.t_end)``, the first instant at or after the edge's end; the last
    edge adds the settle time. One caveat is the pull guide's: the robot's reference over a
    pulling run is computed backward from the run's end (:class:`~pushtrain.core.pulling.
    PullGuide`), so a pulling run split over two continuation edges gets another guide than
    the whole run; append a whole pulling run in one edge (extending a copy keeps the run
    whole and recomputes its guide).

Checks (:class:`Checks`)
    Optionally every state visited is checked, and the run stops at the first violation: every
    body's sample points against a signed distance grid with a per-body margin, every joint
    angle against ``phi_max``, non-adjacent bodies' rectangles against each other (separating
    axes); a non-finite state always stops a run. The :class:`Violation` says where.

Units: SI, radians; chain conventions of :mod:`pushtrain.core.kinematics`.
"""

from __future__ import annotations

import ctypes
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pushtrain.defaults import PULL_GUIDE_STEP, ROLLOUT_SETTLE_TIME, ROLLOUT_STEP
from pushtrain.errors import ControllerError, ReferencePathError

from . import native
from .controller import ControllerConfig, controller_struct
from .kinematics import ChainGeometry, body_positions, joint_angles
from .pulling import PullGuide
from .reference import Reference

__all__ = [
    "REASONS",
    "Checks",
    "ClosedLoopEngine",
    "LoopState",
    "EngineRun",
    "Violation",
    "join_runs",
    "rectangle_points",
    "simulate",
]

REASONS = {1: "non_finite", 2: "footprint", 3: "joint_limit", 4: "self_collision", 5: "control"}
"""The :attr:`Violation.reason` of each C stop code (``PT_STOP_*`` in ``rollout.h``)."""


@dataclass(frozen=True, eq=False)
class LoopState:
    """Everything a run continues from.

    Attributes
    ----------
    k : int
        Index of the control instant: time ``t_start + k * step``.
    z : (3 + n,) array
        Robot position and all headings ``(x0, y0, theta_0..theta_n)`` [m, m, rad].
    v_prev, w_prev : float
        The controller's previous command [m/s, rad/s] (its rate limits continue from it).
    t_prev : float or None
        Its time [s] (None: the next command is not rate limited).
    """

    k: int
    z: np.ndarray
    v_prev: float = 0.0
    w_prev: float = 0.0
    t_prev: float | None = None

    @property
    def headings(self) -> np.ndarray:
        """theta_0..theta_n [rad]."""
        return self.z[2:].copy()

    @property
    def phi(self) -> np.ndarray:
        """Joint angles phi_i = theta_{i-1} - theta_i [rad], wrapped to (-pi, pi] as the
        engine's joint check wraps them (:func:`~pushtrain.core.kinematics.joint_angles`)."""
        return joint_angles(self.z[2:])


@dataclass(frozen=True)
class Violation:
    """The first failed check of a run.

    ``reason`` is one of :data:`REASONS`' values; ``step`` the instant index k and ``t`` its
    time [s]; ``body`` 0 (robot) .. n and ``other`` the second body of a self-collision (else
    None); ``(x, y)`` [m] the failing sample point (footprint), the trailer's position (joint
    limit), a point of the overlap (self-collision), or the robot's position; ``value`` the
    interpolated distance [m] there (footprint), the joint angle [rad] (joint limit) or the C
    status code (control: the reference, the leader or the controller refused).
    """

    reason: str
    step: int
    t: float
    body: int
    other: int | None
    x: float
    y: float
    value: float


@dataclass
class EngineRun:
    """One run of :meth:`ClosedLoopEngine.run` from instant k0 to the instant it ended at, k1.

    Attributes
    ----------
    t : (K + 1,) array
        Times [s] of the instants k0..k1.
    states : (K + 1, 3 + n) array
        ``(x0, y0, theta_0..theta_n)`` at those instants (empty rows if not recorded).
    commands : (K, 2) array
        The command (v0 [m/s], w0 [rad/s]) held from instant k0 + j on.
    reference : (K, 3) array
        The last trailer's reference pose (x, y, theta) at those instants.
    direction : (K,) int array
        The reference's direction there (PUSH +1, PULL -1, REST 0).
    end : LoopState
        Where the run ended (continue from it).
    violation : Violation or None
        Why it ended early, if it did.
    """

    t: np.ndarray
    states: np.ndarray
    commands: np.ndarray
    reference: np.ndarray
    direction: np.ndarray
    end: LoopState
    violation: Violation | None

    def head(self, k: int) -> EngineRun:
        """The run's rows up to instant ``k`` (after its first instant, at most its last
        recorded one): a run that ends there, in the state it was in then (the controller's
        previous command and its time included), so that continuing it from its ``end``
        gives, bit for bit, what the rest of this run gave with the same reference."""
        k0 = self.end.k - (self.t.shape[0] - 1)
        j = int(k) - k0
        if not (1 <= j < self.t.shape[0]) or self.states.shape[0] != self.t.shape[0]:
            raise ControllerError(f"head: instant {k} is not after the first instant {k0} of "
                                  f"a recorded run ending at {self.end.k}")
        v_prev, w_prev = (float(c) for c in self.commands[j - 1])
        end = LoopState(int(k), self.states[j].copy(), v_prev, w_prev, float(self.t[j - 1]))
        return EngineRun(self.t[:j + 1], self.states[:j + 1], self.commands[:j],
                         self.reference[:j], self.direction[:j], end, None)


def join_runs(runs: Sequence[EngineRun]) -> EngineRun:
    """The pieces of one resumed run (each starting where the one before ended) as one
    :class:`EngineRun`: its rows from the first piece's start to the last piece's end, the end
    and violation of the last piece. Recorded pieces only (``run(..., record=True)``)."""
    if not runs:
        raise ControllerError("join_runs: no runs to join")
    if len(runs) == 1:
        return runs[0]
    first, last = runs[0], runs[-1]
    return EngineRun(np.concatenate([first.t] + [r.t[1:] for r in runs[1:]]),
                     np.vstack([first.states] + [r.states[1:] for r in runs[1:]]),
                     np.vstack([r.commands for r in runs]),
                     np.vstack([r.reference for r in runs]),
                     np.concatenate([r.direction for r in runs]), last.end, last.violation)


def rectangle_points(length: float, width: float, offset: float = 0.0,
                     spacing: float = 0.05) -> np.ndarray:
    """Sample points (m, 2) [m] covering a body's rectangle in its own frame.

    The rectangle is ``length`` along the heading and ``width`` across, centred ``offset``
    ahead of the axle midpoint (``BodyFootprint``'s convention). The points form a grid with
    spacing at most ``spacing`` [m] that includes the boundary and corners, so the discs of
    radius ``spacing / sqrt(2)`` around them cover the rectangle: with a true distance field,
    every point of the body is at least ``margin - spacing / sqrt(2)`` from the blocked space
    when all sample points pass a ``margin`` check.
    """
    if not all(math.isfinite(a) for a in (length, width, offset, spacing)) or min(
            length, width, spacing) <= 0.0:
        raise ControllerError(f"rectangle {length!r} x {width!r} m, offset {offset!r} m, spacing "
                              f"{spacing!r} m: need finite sizes and spacing > 0")
    nu = int(math.ceil(length / spacing)) + 1
    nv = int(math.ceil(width / spacing)) + 1
    u = offset + np.linspace(-0.5 * length, 0.5 * length, nu)
    v = np.linspace(-0.5 * width, 0.5 * width, nv)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    return np.column_stack([uu.ravel(), vv.ravel()])


class Checks:
    """What :class:`ClosedLoopEngine` checks at every state it visits.

    Parameters
    ----------
    n : int
        Number of trailers.
    sdf : (ny, nx) array or None
        Signed distance [m] to the blocked space (negative inside it) at the grid points
        ``(origin[0] + j * resolution, origin[1] + i * resolution)``, row ``i``, column ``j``;
        interpolated bilinearly, and nothing outside the grid is free. None: no footprint check.
    origin : (x, y)
        Position [m] of ``sdf[0, 0]``.
    resolution : float
        Grid spacing [m], > 0.
    points : sequence of n + 1 arrays (m_b, 2)
        Sample points of each body (robot first) in its own frame [m] (x along the heading
        from the axle midpoint, y to the left), e.g. :func:`rectangle_points`.
    margins : float or (n + 1,)
        Distance [m] each body's points must keep: a point is free if the interpolated
        distance there is >= its body's margin.
    phi_max : float or None
        Joint limit [rad]: every |phi_i| (wrapped) must stay <= it. None: no joint check.
    rectangles : (n + 1, 4) array or None
        Each body's rectangle for the self-collision check: centre (cx, cy) in its own frame,
        half length, half width [m]. None: no self-collision check.
    fine_points, fine_margins : like ``points`` and ``margins``, or None
        A second test of a body that failed the first at a state: the body passes there if all
        its ``fine_points`` keep its ``fine_margins`` (e.g. ``points`` a few disc centres with
        the discs' radius in the margin, ``fine_points`` the perimeter). None: no second test.
    """

    def __init__(self, n: int, sdf=None, origin=(0.0, 0.0), resolution: float | None = None,
                 points: Sequence | None = None, margins=0.0, phi_max: float | None = None,
                 rectangles=None, fine_points: Sequence | None = None, fine_margins=None):
        self.n = int(n)
        nb = self.n + 1
        self.struct = native.PtChecks()
        self._keep = []
        if sdf is not None:
            grid = np.ascontiguousarray(sdf, dtype=float)
            if grid.ndim != 2 or min(grid.shape) < 2:
                raise ControllerError(f"sdf has shape {grid.shape}: need (ny, nx) with both >= 2")
            if resolution is None or not (math.isfinite(resolution) and resolution > 0.0):
                raise ControllerError(f"resolution = {resolution!r} m: must be finite and > 0")
            offset, px, py, margin = self._point_set(points, margins, "")
            s = self.struct
            s.ny, s.nx = grid.shape
            s.sdf = native.dptr(grid)
            s.x0, s.y0, s.h = float(origin[0]), float(origin[1]), float(resolution)
            s.point_offset = offset.ctypes.data_as(ctypes.POINTER(ctypes.c_int))
            s.px, s.py, s.margin = native.dptr(px), native.dptr(py), native.dptr(margin)
            self._keep += [grid, offset, px, py, margin]
            if fine_points is not None:
                offset, px, py, margin = self._point_set(
                    fine_points, 0.0 if fine_margins is None else fine_margins, "fine_")
                s.fine_offset = offset.ctypes.data_as(ctypes.POINTER(ctypes.c_int))
                s.fine_px, s.fine_py = native.dptr(px), native.dptr(py)
                s.fine_margin = native.dptr(margin)
                self._keep += [offset, px, py, margin]
        if phi_max is not None:
            if not (math.isfinite(phi_max) and phi_max > 0.0):
                raise ControllerError(f"phi_max = {phi_max!r} rad: must be finite and > 0")
            self.struct.phi_max = float(phi_max)
        if rectangles is not None:
            rect = np.ascontiguousarray(rectangles, dtype=float)
            if rect.shape != (nb, 4) or not np.all(np.isfinite(rect)):
                raise ControllerError(f"rectangles has shape {rect.shape}: need ({nb}, 4), finite")
            self.struct.rect = native.dptr(rect)
            self._keep.append(rect)

    def _point_set(self, points, margins, prefix: str):
        """Offsets, x, y and per-body margins of one sample set (``prefix`` names it in
        errors)."""
        nb = self.n + 1
        if points is None or len(points) != nb:
            raise ControllerError(f"{prefix}points: need one (m, 2) array per body, {nb} in all")
        pts = [np.asarray(p, dtype=float).reshape(-1, 2) for p in points]
        offset = np.ascontiguousarray(np.cumsum([0] + [p.shape[0] for p in pts]), dtype=np.intc)
        allp = np.concatenate(pts) if pts else np.zeros((0, 2))
        px, py = np.ascontiguousarray(allp[:, 0]), np.ascontiguousarray(allp[:, 1])
        margin = np.ascontiguousarray(np.broadcast_to(np.asarray(margins, dtype=float),
                                                      (nb,)).copy())
        if not np.all(np.isfinite(margin)):
            raise ControllerError(f"{prefix}margins = {margins!r}: must be finite")
        if not np.all(np.isfinite(allp)):
            raise ControllerError(f"{prefix}points: every coordinate must be finite")
        return offset, px, py, margin

    def sdf_at(self, x: float, y: float) -> float:
        """The interpolated signed distance [m] at (x, y) (-inf outside the grid)."""
        return float(native.load().pt_sdf_at(ctypes.byref(self.struct), float(x), float(y)))


class ClosedLoopEngine:
    """The closed loop of the controller and the kinematic chain, integrated in C.

    Parameters
    ----------
    plant : ChainGeometry
        The train's chain (the controller uses its own model, ``controller.geometry``).
    controller : ControllerConfig
    step : float
        Control and RK4 step [s], > 0 (:data:`pushtrain.defaults.ROLLOUT_STEP`).
    t_start : float
        Time [s] of instant k = 0.
    checks : Checks or None
        Checks at every visited state (None: only non-finite states stop a run).
    guide_step : float
        RK4 step [s] of the pull guide's backward runs (PullGuide's default,
        :data:`pushtrain.defaults.PULL_GUIDE_STEP`).

    The C loop releases the GIL; give each thread its own ClosedLoopEngine (it caches the last
    reference's pull guide).
    """

    def __init__(self, plant: ChainGeometry, controller: ControllerConfig,
                 step: float = ROLLOUT_STEP,
                 t_start: float = 0.0, checks: Checks | None = None,
                 guide_step: float = PULL_GUIDE_STEP):
        if not isinstance(plant, ChainGeometry):
            raise ControllerError(f"plant = {plant!r}: must be a ChainGeometry")
        if not isinstance(controller, ControllerConfig):
            raise ControllerError(f"controller = {controller!r}: must be a ControllerConfig")
        if controller.geometry.n != plant.n:
            raise ControllerError(f"the controller's chain model has n = "
                                  f"{controller.geometry.n} trailers; the plant has {plant.n}")
        for name, value in (("step", step), ("guide_step", guide_step)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
                raise ControllerError(f"{name} = {value!r} s: must be finite and > 0")
        if not (isinstance(t_start, (int, float)) and math.isfinite(t_start)):
            raise ControllerError(f"t_start = {t_start!r} s: must be finite")
        if checks is not None and (not isinstance(checks, Checks) or checks.n != plant.n):
            raise ControllerError(f"checks = {checks!r}: must be Checks for n = {plant.n}")
        self.plant = plant
        self.controller = controller
        self.step = float(step)
        self.t_start = float(t_start)
        self.checks = checks
        self.guide_step = float(guide_step)
        self.n = plant.n
        self._lib = native.load()
        self._front = np.ascontiguousarray(plant.front, dtype=float).copy()
        self._rear = np.ascontiguousarray(plant.rear, dtype=float).copy()
        self._chain = native.PtChain(self.n, native.dptr(self._front), native.dptr(self._rear))
        self._ctrl, self._ctrl_arrays = controller_struct(controller)
        self._work_size = self._lib.pt_rollout_work(self.n)
        self._native_refs: dict[int, tuple] = {}
        self._leader_key: tuple | None = None  # (reference, its phases, its end) of _leader
        self._leader: PullGuide | None = None

    # ------------------------------------------------------------------ time
    def time(self, k: int) -> float:
        """Time [s] of instant ``k``: ``t_start + k * step``."""
        return self.t_start + float(k) * self.step

    def instant_at(self, t: float) -> int:
        """The first instant k at or after time ``t`` [s] (within 1e-9 steps, as
        :func:`simulate` counts its steps)."""
        return int(math.ceil((float(t) - self.t_start) / self.step - 1e-9))

    # ------------------------------------------------------------------ states
    def start(self, last_pose: Sequence[float], headings: Sequence[float], k: int = 0,
              v0: float = 0.0, w0: float = 0.0) -> LoopState:
        """The state at instant ``k`` of a train whose last trailer is at ``last_pose``
        ``(x, y, theta)`` [m, m, rad] with ``headings`` theta_0..theta_n [rad]; the controller's
        previous command is ``(v0, w0)`` one step before (a robot at rest by default, as the
        co-simulation master and :func:`simulate` start)."""
        th = np.asarray(headings, dtype=float).reshape(-1)
        if th.size != self.n + 1 or not np.all(np.isfinite(th)):
            raise ControllerError(f"headings has {th.size} entries: need n + 1 = {self.n + 1}"
                                  " finite headings")
        pose = np.asarray(last_pose, dtype=float).reshape(-1)
        if pose.size != 3 or not np.all(np.isfinite(pose)):
            raise ControllerError(f"last_pose = {last_pose!r}: need three finite numbers")
        x, y = body_positions(pose[0], pose[1], th, self.plant, from_last=True)
        z = np.concatenate(([float(x[0]), float(y[0])], th))
        return LoopState(int(k), z, float(v0), float(w0), self.time(k) - self.step)

    def hold(self, z: Sequence[float], v0: float, w0: float, h: float, count: int) -> np.ndarray:
        """The plant alone under the held command ``(v0, w0)`` [m/s, rad/s]: ``count`` RK4 steps
        of ``h`` [s] from the state ``z`` (3 + n) with the loop's own integrator; the new states,
        (count, 3 + n). For samples between two control instants (the command is held there)."""
        z = np.array(z, dtype=float).reshape(-1)
        if z.shape != (self.n + 3,):
            raise ControllerError(f"z has {z.size} entries: need 3 + n = {self.n + 3}")
        count = int(count)
        out = np.zeros((max(count, 0), self.n + 3))
        status = self._lib.pt_hold(ctypes.byref(self._chain), native.dptr(z), float(v0),
                                   float(w0), float(h), count, native.dptr(out),
                                   native.dptr(np.zeros(self._work_size)))
        if status:
            raise ControllerError(f"hold: {native.STATUS.get(status, status)} (count = {count})")
        return out

    # ------------------------------------------------------------------ running
    def _native(self, reference) -> Reference:
        if isinstance(reference, Reference):
            return reference
        raise ReferencePathError(f"reference = {reference!r}: must be a Reference")

    def leader_for(self, reference) -> PullGuide | None:
        """The pull guide of ``reference`` (None without pulling runs), computed in C with the
        controller's chain model; kept while the reference is unchanged."""
        ref = self._native(reference)
        key = self._leader_key
        if key is None or key[0] is not ref or key[1:] != (ref.struct.n_phases, ref.t_end):
            self._leader = (PullGuide(ref, self.controller.geometry, self.guide_step)
                            if ref.pull_intervals() else None)
            self._leader_key = (ref, ref.struct.n_phases, ref.t_end)
        return self._leader

    def run(self, reference, state: LoopState, k_end: int, record: bool = True) -> EngineRun:
        """Run from ``state`` to instant ``k_end`` (or the first violation).

        Parameters
        ----------
        reference : Reference
            The last trailer's reference (its pull guide is computed here).
        state : LoopState
            Where to start (:meth:`start`, or a previous run's ``end``).
        k_end : int
            The instant to stop at (>= ``state.k``); its command is not computed.
        record : bool
            Keep the states, commands and references of every instant (else only the end).
        """
        ref = self._native(reference)
        leader = self.leader_for(ref)
        if not isinstance(state, LoopState) or state.z.shape != (self.n + 3,):
            raise ControllerError(f"state = {state!r}: must be a LoopState of n = {self.n}")
        k_end = int(k_end)
        if k_end < state.k:
            raise ControllerError(f"k_end = {k_end} is before the state's instant {state.k}")
        rows = k_end - state.k
        nz = self.n + 3
        z = np.array(state.z, dtype=float)
        control = native.PtControlState(state.v_prev, state.w_prev,
                                        0.0 if state.t_prev is None else float(state.t_prev),
                                        0 if state.t_prev is None else 1)
        setup = native.PtRollout(ctypes.pointer(self._chain), ctypes.pointer(self._ctrl),
                                 ctypes.pointer(ref.struct),
                                 None if leader is None else ctypes.pointer(leader.struct),
                                 self.t_start, self.step,
                                 None if self.checks is None else ctypes.pointer(
                                     self.checks.struct))
        if record:
            states, commands = np.zeros((rows + 1, nz)), np.zeros((rows, 2))
            refs, dirs = np.zeros((rows, 3)), np.zeros(rows, dtype=np.intc)
            rec = native.PtRecord(native.dptr(states), native.dptr(commands), native.dptr(refs),
                                  dirs.ctypes.data_as(ctypes.POINTER(ctypes.c_int)))
        else:
            rec = None
        k = ctypes.c_long(state.k)
        violation = native.PtViolation()
        work = np.zeros(self._work_size)  # per run: runs may go on in several threads
        status = self._lib.pt_rollout(ctypes.byref(setup), ctypes.byref(k), native.dptr(z),
                                      ctypes.byref(control), k_end, native.dptr(work),
                                      None if rec is None else ctypes.byref(rec),
                                      ctypes.byref(violation))
        if status:
            raise ControllerError(f"closed-loop run refused its setup: "
                                  f"{native.STATUS.get(status, status)}")
        done = k.value - state.k
        end = LoopState(k.value, z.copy(), control.v_prev, control.w_prev,
                        control.t_prev if control.has_t_prev else None)
        found = None
        if violation.reason:
            found = Violation(REASONS[violation.reason], int(violation.step),
                              self.time(violation.step), int(violation.body),
                              None if violation.other < 0 else int(violation.other),
                              float(violation.x), float(violation.y), float(violation.value))
        t = self.t_start + np.arange(state.k, k.value + 1, dtype=float) * self.step
        if record:
            return EngineRun(t, states[: done + 1], commands[:done], refs[:done],
                           dirs[:done].astype(int), end, found)
        return EngineRun(t, np.zeros((0, nz)), np.zeros((0, 2)), np.zeros((0, 3)),
                       np.zeros(0, dtype=int), end, found)


def simulate(plant: ChainGeometry, reference: Reference, start_headings: Sequence[float],
             controller: ControllerConfig, step: float = ROLLOUT_STEP,
             settle_time: float = ROLLOUT_SETTLE_TIME,
             checks: Checks | None = None) -> EngineRun:
    """The closed loop along a whole reference: the run from t = 0 to the first instant at or
    after ``reference.t_end + settle_time`` [s], the last trailer starting at
    ``reference.start`` with ``start_headings`` (n+1,) [rad], the robot at rest (as the
    co-simulation master starts); ``step`` [s] is the control and RK4 step."""
    loop = ClosedLoopEngine(plant, controller, step, 0.0, checks)
    state = loop.start(reference.start, start_headings)
    return loop.run(reference, state, loop.instant_at(reference.t_end + settle_time))
