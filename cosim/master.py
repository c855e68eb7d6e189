"""Co-simulation master: the TrailerTrain FMU stepped with the backward controller in the loop.

At each communication point ``t_k = t0 + k h`` (default h = 0.005 s, the paper's sampling time)
the loop reads as its three steps:

apply inputs
    the events due (:class:`~pushtrain.cosim.events.EventSchedule`: joint-bias switches, the
    push force on the last trailer, imposed slides), the FMU's states (robot pose, last
    trailer's pose, joint angles) -> the engine's step (``core/csrc/step.c``: sensors with bias,
    noise, quantization and backlash, reference sample, pull guide, Kanayama + inverse chain
    kinematics, push force, tracking errors; one C call,
    :class:`~pushtrain.cosim.step_loop.EngineStep`) -> the FMU's inputs;
record
    every output (read after the inputs: the wheel forces depend directly on them) and the flags
    straight into the recorder's row, with the inputs, the reference and the tracking errors;
    one copy of the row per step (:class:`~pushtrain.cosim.recorder.Recorder`, a numpy
    structured array at the end);
do step
    ``fmi2DoStep`` from t_k to t_k + h, unless the last trailer reached the goal, a joint
    jackknifed or the horizon ended.

Per step that is four FMI calls and one doStep. Two loops do it, with the same results bit for
bit: the compiled step loop (:mod:`~pushtrain.cosim.step_loop`, ``cosim/csrc/master_loop.c``:
up to :data:`~pushtrain.cosim.step_loop.CHUNK` steps per C call, back in Python only for events,
the progress bar, the goal, a jackknife or a failure), used whenever the run allows it (an FMI 2.0
FMU, the compiled control law tracking a line/arc reference); and the Python loop
(:meth:`PythonLoop.run`: the FMI calls through bare ctypes with preallocated arrays
(:class:`~pushtrain.cosim.fmu_slave.TrailerTrainSlave`) and one engine call per step), for
everything else (FMI 3.0; and the governor, open-loop profiles and the Python control law, whose
command is Python between the compiled sensors and the push force and errors in Python).
``simulate(step_loop=...)`` picks one; ``benchmarks/bench_cosim.py`` compares both with a
raw-ctypes loop doing the same calls.

Use :func:`simulate`; it returns a :class:`Result` that can :meth:`~Result.save` CSV, NPZ and
``summary.json`` (each written atomically).
"""

from __future__ import annotations

import ctypes
import logging
import math
import sys
import time as _time
from collections.abc import Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.kinematics import wrap_scalar
from pushtrain.core.native_controller import NativeController, Tracker
from pushtrain.core.reference import Reference
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
from .sensors import SensorConfig, Sensors
from .step_loop import STEP_LOOPS, CompiledLoop, EngineStep, unsupported

__all__ = ["simulate"]

log = logging.getLogger(__name__)

_OUTPUTS = (  # FMU output array, its result column prefix, first index
    ("x", "x", 0), ("y", "y", 0), ("theta", "theta", 0), ("v", "v", 0), ("w", "w", 0),
    ("phi", "phi", 1), ("F_lat", "F_lat", 1), ("slide_speed", "u", 1),
)


_SCALARS = ("t", "v_cmd", "w_cmd", "push_x", "push_y", "slide", "x_d", "y_d", "theta_d", "v_d",
            "w_d", "direction", "e_lon", "e_lat", "e_theta")
"""The columns of a row that are neither FMU values nor measured joint angles, in the order the
loops write them."""


def _columns(n: int) -> list[str]:
    """The result's columns in order (``u{i}`` is the FMU's ``slide_speed[i]`` [m/s])."""
    cols = ["t"]
    for base in ("x", "y", "theta", "v", "w"):
        cols += [f"{base}{i}" for i in range(n + 1)]
    for base in ("phi", "phi_meas", "F_lat", "F_lat_max", "slipping", "u"):
        cols += [f"{base}{i}" for i in range(1, n + 1)]
    cols += ["v_cmd", "w_cmd", "push_x", "push_y", "slide"]
    cols += ["x_d", "y_d", "theta_d", "v_d", "w_d", "direction"]
    cols += ["e_lon", "e_lat", "e_theta", "jackknifed"]
    return cols


def _recorder(n: int, capacity: int, by_column: bool = False) -> Recorder:
    """The recorder of a run: the blocks the loop writes, the columns of :func:`_columns`.

    For the Python loop the FMU's outputs and flags land in their blocks of the recorder's row
    straight from the FMU; ``scalars`` holds the time, the inputs, the reference sample and the
    tracking errors. With ``by_column`` (the compiled loop, which places every value itself) a
    row is laid out in the result's column order, so the table is the storage itself
    (:meth:`Recorder.to_array` copies nothing)."""
    joints = range(1, n + 1)
    if by_column:
        columns = _columns(n)
        starts = [0, 1, columns.index("phi_meas1"), columns.index("F_lat1"),
                  columns.index("F_lat_max1"), columns.index("slipping1"), columns.index("u1"),
                  columns.index("v_cmd"), columns.index("x_d"), len(columns) - 1, len(columns)]
        names = ("t", "states", "phi_meas", "F_lat", "F_lat_max", "slipping", "u", "inputs",
                 "reference", "jackknifed")
        return Recorder([(name, columns[a:b]) for name, a, b in zip(names, starts, starts[1:],
                                                                      strict=False)],
                        columns, capacity)
    blocks = [
        ("outputs", [f"{col}{i}" for _, col, first in _OUTPUTS for i in range(first, n + 1)]),
        ("flags", [f"slipping{i}" for i in joints] + ["jackknifed"]),
        ("F_lat_max", [f"F_lat_max{i}" for i in joints]),
        ("phi_meas", [f"phi_meas{i}" for i in joints]),
        ("scalars", list(_SCALARS)),
    ]
    return Recorder(blocks, _columns(n), capacity)


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
    """The FMU's per-step reads and writes, by variable name.

    ``read_state`` fills :attr:`pose` (robot pose, last trailer's pose) and :attr:`phi` (joint
    angles): what the sensors measure, states that setting inputs does not change.
    ``read_outputs`` (every output of ``_OUTPUTS``, in that order) and ``read_flags`` (slipping
    1..n, jackknifed) write into the recorder's row; ``write_slide[i]`` sets ``slide[i]`` for
    the trailers ``slid`` (1..n) that have Slide events."""

    def __init__(self, slave: TrailerTrainSlave, n: int, recorder: Recorder, slid=()):
        self.n = n
        self.state = np.empty(n + 6)
        self.pose, self.phi = self.state[:6], self.state[6:]
        self.state_names = ["x[0]", "y[0]", "theta[0]", f"x[{n}]", f"y[{n}]", f"theta[{n}]",
                            *slave.names("phi", 1, n)]
        self.output_names = [f"{fmu}[{i}]" for fmu, _, first in _OUTPUTS
                             for i in range(first, n + 1)]
        self.output_columns = [f"{col}{i}" for _, col, first in _OUTPUTS
                               for i in range(first, n + 1)]
        self.flag_names = [*slave.names("slipping", 1, n), "jackknifed"]
        self.flag_columns = [f"slipping{i}" for i in range(1, n + 1)] + ["jackknifed"]
        self.input_names = ["v_cmd", "w_cmd", "push_x", "push_y"]
        self.read_state = slave.real_reader(self.state_names, out=self.state)
        rows = recorder.has("outputs")  # the Python loop's layout: read straight into the row
        self.read_outputs = slave.real_reader(self.output_names,
                                              out=recorder.view("outputs") if rows else None)
        self.read_flags = slave.bool_reader(self.flag_names,
                                            out=recorder.view("flags") if rows else None)
        self.write_inputs = slave.real_writer(self.input_names)
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


class PythonLoop:
    """One run's loop in Python: at each communication point apply the inputs, record,
    ``fmi2DoStep`` (:class:`~pushtrain.cosim.step_loop.CompiledLoop` runs the same in C, given
    this object). :meth:`goal_reached` and :meth:`jackknife` are the run's end tests, which the
    compiled loop leaves to Python."""

    scalar_columns = _SCALARS
    """The row's columns besides the FMU's values and the measured joint angles."""

    def __init__(self, slave, loop: TrackingLoop, sensors: Sensors, events: EventSchedule,
                 recorder: Recorder, goal: _Goal):
        self.slave, self.loop, self.sensors, self.events = slave, loop, sensors, events
        self.recorder, self.goal, self.n = recorder, goal, sensors.n
        slid = {self.n if ev.trailer is None else ev.trailer for ev in events.slides}
        self.io = _PlantIO(slave, self.n, recorder, sorted(slid))

    def run(self, t0: float, step: float, n_steps: int, bar=None) -> tuple[str, str] | None:
        """Step from ``t0`` (communication points t0 + k step, k = 0..n_steps); the status and
        message of a jackknife or the goal, or None if the horizon ended first.

        Per step: four FMI calls, one doStep, scalar Python and one copy of the row (the
        per-step objects are bound to locals once)."""
        recorder = self.recorder
        self.flags = recorder.view("flags")
        # the engine's step reads the FMU's states and writes the joint readings into the row
        tracker = getattr(self.loop.command, "__self__", None)
        engine = EngineStep(self.io.state, recorder.view("phi_meas"), self.sensors, self.events,
                            self.loop.command, tracker if isinstance(tracker, Tracker) else None)
        scalars = recorder.view("scalars")  # t, inputs, reference sample, errors: set at once
        self.scalars = (ctypes.c_double * len(scalars)).from_buffer(scalars)
        events, io, n, goal = self.events, self.io, self.n, self.goal
        read_state, write_inputs = io.read_state, io.write_inputs
        read_outputs, read_flags = io.read_outputs, io.read_flags
        last_pose, engine_step = io.pose[3:], engine.step
        scalars, flags, commit = self.scalars, self.flags, self.recorder.commit
        do_step = self.slave.do_step
        for k in range(n_steps + 1):
            t = t0 + k * step
            # apply inputs: events due, states -> the engine's step (sensors, law, push force,
            # tracking errors) -> FMU inputs
            if events.biases:
                for bias in events.biases_due(t):
                    self.sensors.set_bias(bias.joint, bias.bias)
            read_state()
            v_cmd, w_cmd, ref, outputs = engine_step(t)
            push_x, push_y = outputs[:2]
            write_inputs((v_cmd, w_cmd, push_x, push_y))
            slide = self._slide(t) if events.slides else 0.0
            # record: every output and the flags, read after the inputs (the wheel forces depend
            # directly on them), the time, inputs, reference and errors; one copy of the row
            read_outputs()
            read_flags()
            scalars[:] = (t, v_cmd, w_cmd, push_x, push_y, slide) + ref + outputs[2:]
            commit()
            if flags[n]:
                return self.jackknife(t)
            if goal.check and t >= goal.t_end - 1e-12:
                reached = self.goal_reached(t, *last_pose.tolist())
                if reached is not None:
                    return reached
            if k == n_steps:
                return None
            # do step
            do_step(t, step)
            if bar is not None and k % 200 == 0:
                bar.update(200 if k else 0)
        return None

    def _slide(self, t: float) -> float:
        """Set the slide speeds [m/s] that change at ``t``; the last trailer's."""
        for i, speed in self.events.slide_changes(t):
            self.io.write_slide[i]((speed,))
        return self.events.slide_speed(self.n)

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
    controller: ControllerConfig | NativeController,
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
    step_loop: str = "auto",
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
        law (:class:`~pushtrain.core.native_controller.NativeController`: reference sample, pull
        leader and command in one C call per step); or a controller built already (a
        NativeController, possibly wrapped by the slip governor: GovernedController; or an
        open-loop profile), used as it is.
    sensors : SensorConfig or Sensors, optional
        Measurement errors; default perfect sensors.
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
    step_loop : {"auto", "c", "python"}
        Which loop steps the run: ``"auto"`` the compiled step loop
        (:mod:`~pushtrain.cosim.step_loop`: many steps per C call) when the run allows it (an
        FMI 2.0 FMU, the compiled control law on a line/arc reference, :class:`Sensors`), else
        the Python loop; ``"c"`` the compiled loop or a CosimInputError saying why not;
        ``"python"`` the Python loop. Both give the same results bit for bit; the summary's
        ``step_loop`` says which ran (and ``step_loop_fallback`` why not the compiled one).

    Raises
    ------
    CosimError
        Bad configuration, detected before any stepping (the FMU's own errors during a run end
        the run with status ``fmu_error`` instead).
    """
    if step_loop not in STEP_LOOPS:
        raise CosimInputError(f"step_loop = {step_loop!r}: allowed are "
                              f"{', '.join(map(repr, STEP_LOOPS))}")
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
    why_not_c = (unsupported(slave, loop, sens) if step_loop != "python"
                 else "step_loop = 'python' was asked for")
    if step_loop == "c" and why_not_c is not None:
        slave.close()
        raise CosimInputError(f"step_loop = 'c': the compiled step loop cannot run {why_not_c}; "
                              "allowed for this run are 'auto' and 'python'")
    # rows for the whole run up to 8 MiB (pages never written cost no memory), then doubling
    recorder = _recorder(n, min(n_steps + 1, max(4096, (8 << 20) // (8 * len(_columns(n))))),
                         by_column=why_not_c is None)
    show = progress if progress is not None else (sys.stderr.isatty() and n_steps > 200)
    wall_start = _time.perf_counter()
    try:
        slave.start({**plant.start_values(), **initial.start_values()}, t0)
        run = PythonLoop(slave, loop, sens, schedule, recorder, goal)
        stepper = run if why_not_c is not None else CompiledLoop(run)
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
    summary["step_loop"] = "python" if why_not_c is not None else "c"
    if why_not_c is not None:
        summary["step_loop_fallback"] = why_not_c
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
        ctrl = NativeController(controller)
    elif hasattr(controller, "command") and hasattr(controller, "n"):
        ctrl = controller  # a built controller, the slip governor or an open-loop profile
    else:
        raise CosimInputError(
            f"controller = {controller!r}: need a ControllerConfig or a built controller "
            "(NativeController, GovernedController, an open-loop profile)"
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
