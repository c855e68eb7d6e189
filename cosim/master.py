"""Co-simulation master: the TrailerTrain FMU stepped with the backward controller in the loop.

At each communication point ``t_k = t0 + k h`` (default h = 0.005 s, the paper's sampling time)
the loop reads as its three steps:

apply inputs
    the events due (:class:`~pushtrain.cosim.events.EventSchedule`: joint-bias switches, the
    push force on the last trailer, imposed slides), the FMU's states (robot pose, last
    trailer's pose, joint angles) -> the engine's step (``core/csrc/step.c``: sensors with bias,
    noise, quantization and backlash, reference sample, pull guide, Kanayama + inverse chain
    kinematics, push force, tracking errors; one C call) -> the FMU's inputs;
record
    every output (read after the inputs: the wheel forces depend directly on them) and the flags
    straight into the recorder's row, with the inputs, the reference and the tracking errors;
    one copy of the row per step (:class:`~pushtrain.cosim.recorder.Recorder`, a numpy
    structured array at the end);
do step
    ``fmi2DoStep`` from t_k to t_k + h, unless the last trailer reached the goal, a joint
    jackknifed or the horizon ended.

Per step that is four FMI calls and one doStep, in one loop: the step loop in C
(:mod:`~pushtrain.cosim.step_loop`, ``cosim/csrc/master_loop.c``: up to
:data:`~pushtrain.cosim.step_loop.CHUNK` steps per C call, FMI 2.0 and 3.0, back in Python only
for events, the progress bar, the goal, a jackknife or a failure). The compiled law (with the
slip governor) and open-loop profiles (:mod:`~pushtrain.core.openloop`: their table) run inside
it; only a law written in Python (or the compiled law on a sampled reference) is called back
from it each step. ``tests/reference/master_loop.py`` writes the same loop step by step in
Python; the tests hold the two equal bit for bit, and ``benchmarks/bench_cosim.py`` times the
loop against a raw-ctypes loop doing the same calls.

Use :func:`simulate`; it returns a :class:`Result` that can :meth:`~Result.save` CSV, NPZ and
``summary.json`` (each written atomically).
"""

from __future__ import annotations

import logging
import math
import sys
import time as _time
from collections.abc import Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pushtrain.core.controller import Controller, ControllerConfig
from pushtrain.core.kinematics import wrap_scalar
from pushtrain.core.reference import Reference
from pushtrain.core.sensors import SensorConfig, Sensors
from pushtrain.core.tracking import TrackingLoop
from pushtrain.defaults import GOAL_TOLERANCE, SETTLE_TIME
from pushtrain.errors import ControllerError, CosimError, CosimInputError
from pushtrain.table1 import SAMPLING_TIME

from .events import EventSchedule, positive_number
from .fmu_slave import TrailerTrainSlave
from .plant import InitialState, PlantConfig
from .recorder import Recorder
from .result import (
    STATUS_COMPLETED,
    STATUS_FMU_ERROR,
    STATUS_GOAL,
    STATUS_JACKKNIFE,
    STATUS_NOT_REACHED,
    STATUS_TIME_LIMIT,
    Result,
    summarize,
)
from .step_loop import StepLoop

__all__ = ["simulate"]

log = logging.getLogger(__name__)

_OUTPUTS = (  # FMU output array, its result column prefix, first index
    ("x", "x", 0), ("y", "y", 0), ("theta", "theta", 0), ("v", "v", 0), ("w", "w", 0),
    ("phi", "phi", 1), ("F_lat", "F_lat", 1), ("slide_speed", "u", 1),
)


_SCALARS = ("t", "v_cmd", "w_cmd", "push_x", "push_y", "slide", "x_d", "y_d", "theta_d", "v_d",
            "w_d", "direction", "e_lon", "e_lat", "e_theta")
"""The columns of a row that are neither FMU values nor measured joint angles, in the order the
loop writes them."""


def _blocks(n: int) -> list[tuple[str, list[str]]]:
    """The result's columns in order, in the blocks the loop writes (``u{i}`` is the FMU's
    ``slide_speed[i]`` [m/s])."""
    bodies, joints = range(n + 1), range(1, n + 1)
    return [("t", ["t"]),
            ("states", [f"{base}{i}" for base in ("x", "y", "theta", "v", "w") for i in bodies]
             + [f"phi{i}" for i in joints]),
            *((block, [f"{block}{i}" for i in joints])
              for block in ("phi_meas", "F_lat", "F_lat_max", "slipping")),
            ("u", [f"u{i}" for i in joints]),
            ("inputs", ["v_cmd", "w_cmd", "push_x", "push_y", "slide"]),
            ("reference", ["x_d", "y_d", "theta_d", "v_d", "w_d", "direction"]),
            ("errors", ["e_lon", "e_lat", "e_theta"]),
            ("jackknifed", ["jackknifed"])]


def _columns(n: int) -> list[str]:
    """The result's columns in order."""
    return [column for _, columns in _blocks(n) for column in columns]


def _steps(horizon: float, step: float) -> int:
    ratio = horizon / step
    if not (math.isfinite(ratio) and ratio < 1e12):
        raise CosimInputError(f"horizon = {horizon!r} s with step = {step!r} s: more than 1e12 "
                              "steps; choose a shorter horizon or a longer step")
    k = round(ratio)
    if abs(ratio - k) > 1e-9 * max(1.0, ratio) or k < 1:
        raise CosimInputError(
            f"step = {step!r} s does not divide the horizon {horizon!r} s into whole steps "
            f"(ratio {ratio:.9g}); choose a step that divides it"
        )
    return int(k)


class _PlantIO:
    """The names of the FMU's per-step reads and writes: :attr:`state_names` (robot pose, last
    trailer's pose, joint angles: what the sensors measure, states that setting inputs does not
    change), :attr:`input_names`, :attr:`output_names` (every output of ``_OUTPUTS``, in that
    order, recorded in :attr:`output_columns`), :attr:`flag_names` (slipping 1..n, jackknifed;
    :attr:`flag_columns`); ``write_slide[i]`` sets ``slide[i]`` for the trailers ``slid``
    (1..n) that have Slide events. The lateral force limits go into the recorder's row."""

    def __init__(self, slave: TrailerTrainSlave, n: int, recorder: Recorder, slid=()):
        self.state_names = ["x[0]", "y[0]", "theta[0]", f"x[{n}]", f"y[{n}]", f"theta[{n}]",
                            *slave.names("phi", 1, n)]
        self.output_names = [f"{fmu}[{i}]" for fmu, _, first in _OUTPUTS
                             for i in range(first, n + 1)]
        self.output_columns = [f"{col}{i}" for _, col, first in _OUTPUTS
                               for i in range(first, n + 1)]
        self.flag_names = [*slave.names("slipping", 1, n), "jackknifed"]
        self.flag_columns = [f"slipping{i}" for i in range(1, n + 1)] + ["jackknifed"]
        self.input_names = ["v_cmd", "w_cmd", "push_x", "push_y"]
        self.write_slide = {i: slave.real_writer([f"slide[{i}]"]) for i in slid}
        recorder.view("F_lat_max")[:] = slave.get_reals(slave.names("F_lat_max", 1, n))


@dataclass(frozen=True)
class _Goal:
    """When a run stops at the goal: ``check`` on, from ``t_end`` [s] on, the last trailer
    within ``position`` [m] and ``heading`` [rad] of ``pose``."""

    check: bool
    pose: np.ndarray
    t_end: float
    position: float
    heading: float

    @classmethod
    def of(cls, reference, check: bool, tolerance) -> _Goal:
        """The goal test of ``reference`` (none without a reference: open loop)."""
        position = positive_number("goal_tolerance[0]", tolerance[0])
        heading = positive_number("goal_tolerance[1]", tolerance[1])
        if reference is None:
            return cls(False, np.full(3, np.nan), math.inf, position, heading)
        return cls(check, np.asarray(reference.goal, dtype=float), float(reference.t_end),
                   position, heading)


class _Ends:
    """The run's end tests that the step loop leaves to Python: :meth:`goal_reached` (the exact
    test of a goal candidate) and :meth:`jackknife` (its message)."""

    def __init__(self, goal: _Goal, recorder: Recorder, n: int):
        self.goal, self.recorder, self.n = goal, recorder, n

    def goal_reached(self, t: float, x_n: float, y_n: float, th_n: float):
        """Status and message if the last trailer's pose is within the goal's tolerance."""
        goal = self.goal
        dist = math.hypot(x_n - goal.pose[0], y_n - goal.pose[1])
        if dist <= goal.position and abs(wrap_scalar(th_n - goal.pose[2])) <= goal.heading:
            return STATUS_GOAL, (
                f"goal reached at t = {t:.3f} s ({dist * 100:.1f} cm from the goal)"
            )
        return None

    def jackknife(self, t: float) -> tuple[str, str]:
        """Status and message of a jackknife at ``t``, naming the worst joint."""
        phi = np.array([self.recorder.last(f"phi{i}") for i in range(1, self.n + 1)])
        worst = int(np.argmax(np.abs(phi))) + 1
        return STATUS_JACKKNIFE, (
            f"jackknife at t = {t:.3f} s: |phi[{worst}]| = "
            f"{math.degrees(abs(phi[worst - 1])):.1f} deg exceeds phi_max"
        )


def _horizon_end(recorder: Recorder, goal: _Goal, horizon: float, n: int) -> tuple[str, str]:
    """Status and message of a run that used its whole horizon."""
    if not goal.check:
        return STATUS_COMPLETED, f"ran the full horizon of {horizon:.3f} s"
    t_last = recorder.last("t")
    if t_last < goal.t_end:
        return STATUS_TIME_LIMIT, (f"time limit {horizon:.3f} s reached before the reference "
                                   f"ended ({goal.t_end:.3f} s)")
    dist = math.hypot(recorder.last(f"x{n}") - goal.pose[0], recorder.last(f"y{n}") - goal.pose[1])
    return STATUS_NOT_REACHED, (
        f"the reference ended at t = {goal.t_end:.3f} s but the last trailer was "
        f"still {dist * 100:.1f} cm from the goal at t = {t_last:.3f} s "
        f"(tolerance {goal.position * 100:.1f} cm, {math.degrees(goal.heading):.1f} deg)")


def simulate(
    fmu,
    reference: Reference,
    controller: ControllerConfig | Controller,
    sensors: SensorConfig | Sensors | None = None,
    events: Sequence = (),
    *,
    plant: PlantConfig | None = None,
    initial: InitialState | None = None,
    step: float = SAMPLING_TIME,
    horizon: float | None = None,
    settle_time: float = SETTLE_TIME,
    goal_tolerance: tuple[float, float] = GOAL_TOLERANCE,
    check_goal: bool = True,
    progress: bool | None = None,
    out_dir=None,
) -> Result:
    """Co-simulate the FMU with the backward controller tracking ``reference``.

    Parameters
    ----------
    fmu : path-like
        A TrailerTrain ``.fmu`` (see :func:`pushtrain.fmu.build.build_fmu`): FMI 2.0 built for the
        controller's n, or FMI 3.0 (configured for that n).
    reference : Reference or SampledReference
        The last trailer's reference.
    controller : ControllerConfig or a built controller
        Gains, limits and the controller's own chain model, computed by the compiled control
        law (:class:`~pushtrain.core.controller.Controller`: reference sample, pull
        leader and command in one C call per step); or a controller built already (a
        Controller, possibly wrapped by the slip governor: GovernedController; or an
        open-loop profile), used as it is.
    sensors : SensorConfig or Sensors, optional
        Measurement errors; default perfect sensors. The noise is drawn in blocks of steps: a
        :class:`Sensors` given here ends the run with its generator up to
        :data:`~pushtrain.cosim.step_loop.CHUNK` - 1 steps of draws past what the run used
        (give each run its own, or ``reset()`` it, to repeat a run).
    events : sequence of Push, Slide, SetBias
    plant : PlantConfig, optional
        FMU parameters; default: the FMU's (Table 1) with the FMU's n.
    initial : InitialState, optional
        Default: a straight train whose last trailer starts on the reference.
    step : float
        Communication step h [s].
    horizon : float, optional
        Run length [s]; default: the reference's end plus ``settle_time``. Must be a whole
        number of steps. Memory grows with the steps actually run, not with the horizon.
    goal_tolerance : (float, float)
        Position [m] and heading [rad] tolerance on the last trailer at the goal.
    check_goal : bool
        Stop with ``goal_reached`` once the reference has ended and the last trailer is within
        tolerance; if False, run the whole horizon (status ``completed``).
    progress : bool or None
        Show a progress bar; None: only when stderr is a terminal and the run is long.
    out_dir : path-like, optional
        Save the results there (also when the run ends in an error status): ``results.npz``
        and ``summary.json`` (:meth:`~pushtrain.cosim.result.Result.save`; call it yourself
        with ``csv=True`` for ``results.csv`` too).

    Raises
    ------
    CosimError
        Bad configuration, detected before any stepping (the FMU's own errors during a run end
        the run with status ``fmu_error`` instead).
    """
    step = positive_number("step", step)
    t0, horizon = _timing(reference, initial, step, horizon, settle_time)
    n_steps = _steps(horizon, step)
    goal = _Goal.of(reference, check_goal, goal_tolerance)
    ctrl, sens, plant = _parts(controller, sensors, plant)
    n = ctrl.n
    schedule = EventSchedule(events, n, t0 + horizon)
    if schedule.slides and plant.slip_mode == 1:
        raise CosimInputError("Slide events impose a kinematic slide (slip_mode 0); with "
                              "slip_mode = 1 the wheels slide physically: use Push events instead")
    if initial is None:
        initial = InitialState.behind_reference(reference, plant.geometry())
    if len(initial.theta) != n + 1:
        raise CosimInputError(
            f"initial.theta has {len(initial.theta)} headings; need n + 1 = {n + 1}"
        )
    if hasattr(ctrl, "reset"):
        # rate limits start from the robot's initial velocity one step before t0
        ctrl.reset(initial.v0, initial.w0, t0 - step)
    loop = TrackingLoop(ctrl, reference, info=False)  # the row records no ControlInfo

    slave = TrailerTrainSlave(fmu, n_trailers=n)  # FMI 3.0: configured for n; FMI 2.0: fixed
    if slave.n != n:
        slave.close()
        raise CosimInputError(
            f"the FMU {Path(fmu).name} has n = {slave.n} trailers; "
            f"the controller's chain has {n}"
        )
    # rows for the whole run up to 8 MiB (pages never written cost no memory), then doubling
    recorder = Recorder(_blocks(n),
                        capacity=min(n_steps + 1, max(4096, (8 << 20) // (8 * len(_columns(n))))))
    show = progress if progress is not None else (sys.stderr.isatty() and n_steps > 200)
    wall_start = _time.perf_counter()
    try:
        slave.start({**plant.start_values(), **initial.start_values()}, t0)
        slid = {n if ev.trailer is None else ev.trailer for ev in schedule.slides}
        io = _PlantIO(slave, n, recorder, sorted(slid))
        stepper = StepLoop(slave, io, loop, sens, schedule, recorder,
                           _Ends(goal, recorder, n), _SCALARS)
        with _progress_bar(show, n_steps) as bar:
            end = stepper.run(t0, step, n_steps, bar)
        status, message = end or _horizon_end(recorder, goal, horizon, n)
    except CosimError as exc:
        status, message = STATUS_FMU_ERROR, str(exc)
        log.error("%s", message)
    except ControllerError as exc:
        status, message = STATUS_FMU_ERROR, f"controller failed: {exc}"
        log.error("%s", message)
    finally:
        fmu_log = slave.last_messages()
        slave.close()
    wall = _time.perf_counter() - wall_start

    data = recorder.to_array()
    summary = summarize(data, n, status, message, wall, step)
    result = Result(status, message, data, summary, n, fmu_log)
    log.info("co-simulation %s: %s (%d steps, %.2f s wall)", status, message, len(data) - 1, wall)
    if out_dir is not None:
        result.save(out_dir)
    return result


def _timing(reference, initial, step: float, horizon, settle_time) -> tuple[float, float]:
    """Start time and horizon [s] of a run (a reference's end plus ``settle_time`` by default,
    rounded up to whole steps); an open-loop run (no reference) needs a horizon and an initial
    state."""
    settle_time = positive_number("settle_time", settle_time, allow_zero=True)
    if reference is None:
        if horizon is None or initial is None:
            raise CosimInputError(
                "a run without a reference (open loop) needs a horizon and an initial state"
            )
    elif not (hasattr(reference, "sample_at") and hasattr(reference, "t_end")):
        raise CosimInputError(f"reference = {reference!r}: need a Reference or SampledReference")
    t0 = float(getattr(reference, "t0", 0.0))
    if horizon is None:
        horizon = float(reference.t_end) - t0 + settle_time
        horizon = step * math.ceil(horizon / step - 1e-9)
    return t0, positive_number("horizon", horizon)


def _parts(controller, sensors, plant):
    """The controller, the sensors and the plant configuration of a run, checked against each
    other's number of trailers."""
    if isinstance(controller, ControllerConfig):
        ctrl = Controller(controller)
    elif hasattr(controller, "command") and hasattr(controller, "n"):
        ctrl = controller  # a built controller, the slip governor or an open-loop profile
    else:
        raise CosimInputError(
            f"controller = {controller!r}: need a ControllerConfig or a built controller "
            "(Controller, GovernedController, an open-loop profile)"
        )
    n = ctrl.n
    sens = sensors if isinstance(sensors, Sensors) else Sensors(sensors or SensorConfig(n_joints=n))
    if sens.n != n:
        raise CosimInputError(f"sensors measure {sens.n} joints; the controller's chain has {n}")
    plant = plant or PlantConfig(n_trailers=n)
    if plant.n_trailers != n:
        raise CosimInputError(
            f"plant.n_trailers = {plant.n_trailers}; the controller's chain has {n}"
        )
    return ctrl, sens, plant


@contextmanager
def _progress_bar(show: bool, total: int):
    """A tqdm bar on stderr if ``show``, else None."""
    if not show:
        yield None
        return
    from tqdm import tqdm

    bar = tqdm(total=total, unit="step", desc="co-simulating", mininterval=0.5, file=sys.stderr)
    try:
        yield bar
    finally:
        bar.close()
