"""The co-simulation's closed loop on the kinematic chain: what the planner predicts of a plan.

The planner plans the last trailer only. Here the whole train's motion along the plan is
predicted by running the co-simulation's own control law in closed loop with the kinematic
chain, on the one closed-loop engine of :mod:`pushtrain.core.engine` (``core/csrc``: the same
compiled law the co-simulation master calls):

Reference
    ``Reference.from_segments(start, segments, tracker.speed, tracker.cusp_dwell)``, the same
    time-parameterized reference :meth:`~pushtrain.planner.path.PlannedPath.to_reference`
    hands to the co-simulation master.
Controller
    ``tracker.controller`` (gains, robot limits, rate limits and its own chain model, from which
    the robot's pulling reference, the pull guide, is built), called every ``tracker.step``
    seconds at ``t_k = k * step`` with a perfect measurement (robot pose and joint angles
    ``phi_i = theta_{i-1} - theta_i``); the command is held over the step (zero-order hold) and
    the rate limits start from rest one step before t = 0, as in the master.
Plant
    The robot moves along its heading with the commanded ``(v0, w0)`` (no first-order velocity
    lag: the FMU's ``tau`` = 0.05 s is ignored, no slip), the trailers are towed (the forward
    velocity map of :mod:`pushtrain.core.kinematics`) with the train's own geometry (the
    controller's model may differ). The state ``(x0, y0, theta_0..theta_n)`` is integrated with
    RK4 over each step (the command is constant within a step). The error is that of the
    zero-order hold, first order in the step: on a bay plan with a cusp and 0.24 m transients
    (3 trailers) the last trailer's trajectory differs from a 0.002 s run by 2.4 cm with a
    0.1 s step, 1.0 cm with 0.05 s and 0.36 cm with the default 0.025 s (a test keeps it below
    1 cm).
Start and end
    The last trailer starts at ``start`` with the given headings (the co-simulation's
    ``InitialState.behind_reference``), at rest. The run continues ``tracker.settle_time``
    seconds past the reference's end (the reference then rests and the robot brakes to a
    stop within its acceleration limit).

The readable Python loop this engine runs is the tests' reference
(``tests/reference/closed_loop.py``), held equal to it bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.engine import ClosedLoopEngine
from pushtrain.core.kinematics import ChainGeometry
from pushtrain.core.reference import Reference
from pushtrain.core.segment import Segment
from pushtrain.defaults import CUSP_DWELL, GOAL_TOLERANCE, REFERENCE_SPEED
from pushtrain.errors import ControllerError, PlanningInputError

__all__ = ["TrackerConfig", "Trajectory", "default_controller", "reference_times",
           "simulate_tracking"]


def default_controller(geometry: ChainGeometry) -> ControllerConfig:
    """:class:`~pushtrain.core.controller.ControllerConfig`'s defaults (the scenario's) with
    ``geometry`` as the controller's chain model."""
    return ControllerConfig(geometry=geometry)


@dataclass(frozen=True)
class TrackerConfig:
    """How the co-simulation will track the plan (what :func:`check_train` simulates).

    Parameters
    ----------
    controller : ControllerConfig or None
        The co-simulation's controller; None: :func:`default_controller` of the train's
        geometry.
    speed : float
        Reference speed |v_d| [m/s] on every segment without its own speed, > 0.
    cusp_dwell : float
        Rest [s] of the reference at every direction change, >= 0.
    step : float
        Control and integration step [s], > 0 (the controller is called every ``step``).
    settle_time : float
        Simulated time [s] past the reference's end, >= 0.
    goal_tolerance : (float, float) or None
        Position [m] and heading [rad] tolerance of the last trailer at the end of the run
        (the co-simulation's goal test); None: report the goal error only.
    """

    controller: ControllerConfig | None = None
    speed: float = REFERENCE_SPEED
    cusp_dwell: float = CUSP_DWELL
    step: float = 0.025
    settle_time: float = 2.0
    goal_tolerance: tuple[float, float] | None = GOAL_TOLERANCE

    def __post_init__(self):
        if self.controller is not None and not isinstance(self.controller, ControllerConfig):
            raise PlanningInputError(
                f"tracker.controller = {self.controller!r}: must be a ControllerConfig or None")
        checks = (("speed", None), ("step", None), ("cusp_dwell", 0.0), ("settle_time", 0.0))
        for key, low in checks:
            value = getattr(self, key)
            ok = isinstance(value, (int, float)) and math.isfinite(value)
            ok = ok and (value > 0.0 if low is None else value >= low)
            if not ok:
                allowed = "finite and > 0" if low is None else "finite and >= 0"
                raise PlanningInputError(f"tracker.{key} = {value!r}: must be {allowed}")
        if self.goal_tolerance is not None:
            tol = tuple(self.goal_tolerance)
            if len(tol) != 2 or not all(math.isfinite(a) and a > 0.0 for a in tol):
                raise PlanningInputError(
                    f"tracker.goal_tolerance = {self.goal_tolerance!r}: need None or two finite "
                    "numbers > 0 (position [m], heading [rad])")
            object.__setattr__(self, "goal_tolerance", (float(tol[0]), float(tol[1])))

    def controller_for(self, geometry: ChainGeometry) -> ControllerConfig:
        """The controller configuration used for a chain of ``geometry`` (checks its n)."""
        config = self.controller if self.controller is not None else default_controller(geometry)
        if config.geometry.n != geometry.n:
            raise PlanningInputError(
                f"tracker.controller has a chain model of n = {config.geometry.n} trailers; the "
                f"train has n = {geometry.n}")
        return config


def reference_times(segments: Sequence[Segment], speed: float, cusp_dwell: float, s):
    """Time [s] at which the reference of :class:`~pushtrain.core.reference.Reference` (t0 = 0)
    reaches the travelled distance ``s`` [m] (array); at a cusp the arrival (start of the dwell).

    Returns ``(t, knots)`` where ``knots = (t_knots, s_knots)`` is the piecewise-linear map
    t -> s (flat during dwells) for :func:`numpy.interp`.
    """
    t_k, s_k = [0.0], [0.0]
    t, pos, previous = 0.0, 0.0, None
    starts, ends, seg_t0, seg_speed = [], [], [], []
    for seg in segments:
        if previous is not None and seg.direction != previous:
            t += cusp_dwell
            t_k.append(t), s_k.append(pos)
        v = speed if seg.speed is None else seg.speed
        starts.append(pos), seg_t0.append(t), seg_speed.append(v)
        t += seg.length / v
        pos += seg.length
        ends.append(pos)
        t_k.append(t), s_k.append(pos)
        previous = seg.direction
    s = np.asarray(s, dtype=float)
    j = np.clip(np.searchsorted(np.array(ends), s, side="left"), 0, len(ends) - 1)
    times = np.array(seg_t0)[j] + (s - np.array(starts)[j]) / np.array(seg_speed)[j]
    return times, (np.array(t_k), np.array(s_k))


@dataclass
class Trajectory:
    """A closed-loop run of :func:`simulate_tracking` (every row one sample).

    Attributes
    ----------
    t : (K,) array
        Times [s]: the control instants ``k * step`` and, where a step was subdivided for the
        footprint test, intermediate times.
    state : (K, 3 + n) array
        Robot position and all headings ``(x0, y0, theta_0..theta_n)`` [m, m, rad].
    command : (K, 2) array
        Robot command (v0 [m/s], w0 [rad/s]) held from this sample on.
    reference : (K, 3) array
        The last trailer's reference pose (x, y, theta) at ``t``.
    direction : (K,) int array
        Reference direction at ``t`` (PUSH +1, PULL -1, REST 0).
    control : (K,) bool array
        True at the control instants (False at subdivision samples).
    """

    t: np.ndarray
    state: np.ndarray
    command: np.ndarray
    reference: np.ndarray
    direction: np.ndarray
    control: np.ndarray


def simulate_tracking(
    geometry: ChainGeometry,
    reference: Reference,
    start_headings: Sequence[float],
    controller: ControllerConfig,
    step: float = 0.025,
    settle_time: float = 2.0,
) -> Trajectory:
    """Run ``controller`` in closed loop with the kinematic chain along ``reference``.

    Parameters
    ----------
    geometry : ChainGeometry
        The plant's chain (the controller uses its own model ``controller.geometry``).
    reference : Reference
        The last trailer's reference (t0 = 0); the last trailer starts at ``reference.start``.
    start_headings : (n+1,)
        Start headings [rad] of robot and trailers (the last equals the start theta).
    controller : ControllerConfig
    step : float
        Control and RK4 step [s].
    settle_time : float
        Time [s] simulated past ``reference.t_end``.

    Returns
    -------
    Trajectory
        Samples at the control instants ``k * step`` (k = 0..K-1, the last one at or after
        ``t_end + settle_time``).
    """
    loop = ClosedLoopEngine(geometry, controller, step)
    start = loop.start(reference.start, start_headings)
    n_steps = loop.instant_at(reference.t_end + settle_time)
    # one instant more than the trajectory: its command, reference and direction at the last
    # instant (the state after it is dropped)
    run = loop.run(reference, start, n_steps + 1)
    if run.violation is not None:
        raise ControllerError(f"the closed loop stopped at t = {run.violation.t:.6g} s: "
                              f"{run.violation.reason} (value {run.violation.value:g})")
    return Trajectory(step * np.arange(n_steps + 1), run.states[:n_steps + 1], run.commands,
                      run.reference, run.direction, np.ones(n_steps + 1, dtype=bool))
