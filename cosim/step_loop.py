"""The master's compiled step loop (``cosim/csrc/master_loop.c``) and when it can run.

:func:`pushtrain.cosim.master.simulate` steps a run either with its Python loop
(``PythonLoop.run``) or, when the run allows it, with the compiled loop: one C call runs many
communication steps (FMU reads and writes through the FMU's own functions, sensors, the
compiled control law, the recorder's rows, the jackknife and goal tests, ``fmi2DoStep``) and
returns to Python only where Python must act:

* at the top of a step where an event is due (a bias switch, a push or a slide starting or
  ending): Python applies it exactly as the Python loop does, and the next call goes on;
* after a budget of steps (:data:`CHUNK`, or when the recorder's storage is full): the progress
  bar moves;
* at a goal candidate (the last trailer within the goal's tolerance up to 1e-9 relative): Python
  makes the Python loop's own test and stops or steps on;
* at a jackknife, at the horizon's end, on a failed FMI call or a refused control instant:
  Python ends the run with the Python loop's status, message or exception.

Noise comes from the sensors' own ``numpy.random.Generator``: for each call Python draws the
standard normals of its steps in one block, in the order the Python sensors draw them (joints,
robot position, robot heading, last trailer's position and heading), scales them as
``Generator.normal`` does (``0.0 + std * z``), and, if the call stops early, rewinds the
generator and draws again only what the steps run used. A run gives the Python loop's results
bit for bit (``tests/test_master_loop.py``).

:func:`unsupported` says why a run cannot use the compiled loop (then the Python loop runs).
"""

from __future__ import annotations

import ctypes
import math
import struct
from ctypes import POINTER, c_double, c_int, c_long, c_uint, c_void_p

import numpy as np

from pushtrain.core import native
from pushtrain.core.kinematics import wrap_scalar
from pushtrain.core.native_controller import Tracker
from pushtrain.core.reference import ReferenceSample
from pushtrain.errors import CosimError, NativeBuildError

from .sensors import Measurement, Sensors

__all__ = ["CHUNK", "STEP_LOOPS", "CompiledLoop", "EngineStep", "unsupported"]

STEP_LOOPS = ("auto", "c", "python")
"""Values of ``simulate(step_loop=...)``: ``"auto"`` the compiled loop when the run allows it
(:func:`unsupported`), else the Python loop; ``"c"`` the compiled loop or an error; ``"python"``
the Python loop."""

CHUNK = 1024
"""Most steps one call of the compiled loop runs (then the progress bar moves)."""

# reasons pt_master_run returns (master_loop.h PT_LOOP_*)
_PAUSE, _HORIZON, _JACKKNIFE, _GOAL_CANDIDATE, _FMI_ERROR, _CONTROL_ERROR, _ARGUMENT = range(7)
# failed FMI calls (PT_CALL_*)
_GET_STATE, _SET_INPUTS, _SET_SLIDE, _GET_OUTPUTS, _GET_FLAGS, _DO_STEP = range(1, 7)

_U_PTR, _D_PTR, _I_PTR = POINTER(c_uint), native.D_PTR, POINTER(c_int)


class PtMasterLoop(ctypes.Structure):
    """``PtMasterLoop`` of ``master_loop.h``."""

    _fields_ = [
        ("component", c_void_p), ("get_real", c_void_p), ("set_real", c_void_p),
        ("get_boolean", c_void_p), ("do_step", c_void_p),
        ("state_vr", _U_PTR), ("input_vr", _U_PTR), ("output_vr", _U_PTR), ("flag_vr", _U_PTR),
        ("n_outputs", c_int), ("n", c_int),
        ("t0", c_double), ("step", c_double), ("n_steps", c_long),
        ("instant", POINTER(native.PtStep)), ("noise_values", _D_PTR),
        ("noise_per_step", c_int),
        ("rows", _D_PTR), ("row_width", c_int), ("n_output_runs", c_int),
        ("output_runs", _I_PTR), ("flag_at", _I_PTR), ("scalar_at", _I_PTR),
        ("at_phi_meas", c_int), ("at_f_lat_max", c_int), ("f_lat_max", _D_PTR),
        ("check_goal", c_int), ("goal_from", c_double), ("goal_x", c_double),
        ("goal_y", c_double), ("goal_theta", c_double), ("goal_position", c_double),
        ("goal_heading", c_double), ("goal_slack", c_double),
        ("pause_at", c_double), ("next_bias", c_double), ("slide", c_double),
        ("n_slide_writes", c_int), ("slide_vr", _U_PTR), ("slide_values", _D_PTR),
        ("state", _D_PTR), ("outputs", _D_PTR), ("flags", _I_PTR),
        ("k", c_long), ("time", c_double), ("inputs", c_double * 4), ("failed_call", c_int),
        ("failed_slide", c_int), ("fmi_status", c_int), ("control_status", c_int),
    ]


def _library() -> ctypes.CDLL:
    """The native library with the loop's prototypes declared (layout checked)."""
    lib = native.load()
    if getattr(lib, "_pt_master_loop_ready", False):
        return lib
    lib.pt_master_loop_sizeof.restype, lib.pt_master_loop_sizeof.argtypes = ctypes.c_size_t, []
    lib.pt_master_run.restype = c_int
    lib.pt_master_run.argtypes = [POINTER(PtMasterLoop), c_long, c_long]
    size = lib.pt_master_loop_sizeof()
    if size != ctypes.sizeof(PtMasterLoop):
        raise NativeBuildError(f"PtMasterLoop is {size} bytes in the library but "
                               f"{ctypes.sizeof(PtMasterLoop)} in cosim/step_loop.py: the "
                               "binding does not match master_loop.h")
    lib._pt_master_loop_ready = True
    return lib


def unsupported(slave, loop, sensors) -> str | None:
    """Why the compiled loop cannot run a run with this FMU instance, tracking loop and sensors,
    or None if it can."""
    if slave.fmi_version != 2:
        return f"an FMI {slave.md.fmiVersion} FMU (the compiled loop calls FMI 2.0)"
    tracker = getattr(loop.command, "__self__", None)
    if not isinstance(tracker, Tracker):
        return ("the control law is not the compiled one tracking a line/arc Reference "
                "(a governor, an open-loop profile, a law written in Python or a sampled "
                "reference)")
    if tracker.info:
        return "the tracking loop records ControlInfo"
    if type(sensors) is not Sensors:
        return f"sensors of type {type(sensors).__name__} (the compiled loop models Sensors)"
    return None


_SAMPLE_CMD = struct.Struct("@5di4x2d")  # PtTrack's sample (PtSample) and cmd
_OUTPUTS = struct.Struct("@5d")  # PtStep's push and errors


class EngineStep:
    """The closed-loop work of one communication step of the Python loop in C
    (``core/csrc/step.c``), so that the loop itself keeps only the FMU calls and the recording.

    With the compiled control law (``tracker``, a
    :class:`~pushtrain.core.native_controller.Tracker`) a step is one call, ``pt_step``:
    sensors -> reference sample, pull leader and command -> push force and tracking errors. With
    a law in Python (the slip governor, open-loop profiles: ``tracker`` None) the sensors are a
    C call (:meth:`Sensors.measurer`) before the Python ``command(t, measurement)``, and the
    push force and errors are computed in Python, in the C's order (an open loop's reference
    sample is NaN: the sign of a NaN result depends on how a compiler orders the operands, so
    its bits are kept those of Python).

    :attr:`step` ``(t)`` returns ``(v_cmd, w_cmd, ref, (push_x, push_y, e_lon, e_lat,
    e_theta))`` for the FMU's true state in ``truth`` at ``t`` [s] (read before the call) and
    writes the joint readings into ``phi_meas`` (both arrays stay bound to the object).
    """

    def __init__(self, truth: np.ndarray, phi_meas: np.ndarray, sensors: Sensors, events,
                 command, tracker: Tracker | None):
        self.lib = native.load()
        self.truth, self.phi_meas, self.sensors, self.events = truth, phi_meas, sensors, events
        self.tracker = tracker
        self.struct = native.PtStep(None if tracker is None else ctypes.pointer(tracker.instant),
                                    ctypes.pointer(sensors.model))
        self._active: list = []
        self._pushes = np.zeros((1, 3))
        self._at_outputs = native.PtStep.push.offset
        self._truth_ptr, self._phi_ptr = native.dptr(truth), native.dptr(phi_meas)
        if tracker is not None:
            tracker.has_last = bool(sensors.config.measure_last_pose)
            self.step = self._compiled
        else:
            self._measure = sensors.measurer(truth, phi_meas)
            self._command = command
            self.step = self._python

    def _set_pushes(self, t: float) -> None:
        """The pushes acting at ``t`` into the struct (rebuilt only when they change)."""
        active = self.events.active_pushes(t)
        if active != self._active:
            self._active = active
            self._pushes = np.array([(p.fx, p.fy, p.lateral) for p in active] or [(0.0,) * 3])
            self.struct.n_pushes = len(active)
            self.struct.pushes = native.dptr(self._pushes)

    def _compiled(self, t: float):
        if self.events.pushes:
            self._set_pushes(t)
        noise = self.sensors.draw_noise(1)
        k = self.tracker.instant
        status = self.lib.pt_step(ctypes.byref(self.struct), t, self._truth_ptr,
                                  None if noise is None else native.dptr(noise), self._phi_ptr)
        out = _SAMPLE_CMD.unpack_from(k, native.PtTrack.sample.offset)
        ref = tuple.__new__(ReferenceSample, out[:6])
        if status:
            raise self.tracker.error(status, t, self.measurement(), ref)
        return out[6], out[7], ref, _OUTPUTS.unpack_from(self.struct, self._at_outputs)

    def _python(self, t: float):
        v_cmd, w_cmd, _, ref = self._command(t, self._measure())
        x_n, y_n, th_n = self.truth[3:6].tolist()
        push_x, push_y = self.events.push_force(t, th_n) if self.events.pushes else (0.0, 0.0)
        dx, dy = x_n - ref.x, y_n - ref.y  # the last trailer's error in the reference frame
        c, s = math.cos(ref.theta), math.sin(ref.theta)
        return v_cmd, w_cmd, ref, (push_x, push_y, c * dx + s * dy, -s * dx + c * dy,
                                   wrap_scalar(th_n - ref.theta))

    def measurement(self) -> Measurement:
        """The compiled law's last measurement (its joint angles from ``phi_meas``)."""
        m = self.tracker.instant.m
        last = (m.x_n, m.y_n, m.theta_n) if m.has_last else None
        return Measurement(m.x0, m.y0, m.theta0, self.phi_meas.tolist(), last)


def _runs(indices: list[int]) -> list[tuple[int, int, int]]:
    """``(first value, first row index, count)`` of each run of values that land side by side
    in a row (value j goes to row index ``indices[j]``)."""
    runs: list[list[int]] = []
    for j, index in enumerate(indices):
        if runs and runs[-1][1] + runs[-1][2] == index:
            runs[-1][2] += 1
        else:
            runs.append([j, index, 1])
    return [tuple(run) for run in runs]


class CompiledLoop:
    """The compiled step loop of one run (a :class:`~pushtrain.cosim.master.PythonLoop` whose
    :func:`unsupported` is None); :meth:`run` as ``PythonLoop.run``."""

    goal_slack = 1e-9
    """The C loop hands a step back as a goal candidate when the last trailer is within
    (1 + goal_slack) times the goal's tolerances; Python's own test (``math.hypot``) decides."""

    def __init__(self, run):
        self.run_ = run
        self.lib = _library()
        slave, io, n, sensors = run.slave, run.io, run.n, run.sensors
        self.tracker: Tracker = run.loop.command.__self__
        functions = slave.fmi2_functions()
        m = self.m = PtMasterLoop()
        m.component = functions["component"]
        m.get_real, m.set_real = functions["fmi2GetReal"], functions["fmi2SetReal"]
        m.get_boolean, m.do_step = functions["fmi2GetBoolean"], functions["fmi2DoStep"]
        refs = [slave.value_references(names) for names in
                (io.state_names, io.input_names, io.output_names, io.flag_names)]
        self._refs = [(c_uint * len(r))(*r) for r in refs]  # kept alive with the struct
        m.state_vr, m.input_vr, m.output_vr, m.flag_vr = (
            ctypes.cast(r, _U_PTR) for r in self._refs)
        m.n_outputs, m.n = len(io.output_names), n
        # the engine's step: the law's instant, the run's own sensor model and memory (biases,
        # play; noise drawn per call), the pushes set per call
        self.instant = native.PtStep(ctypes.pointer(self.tracker.instant),
                                     ctypes.pointer(sensors.model))
        m.instant = ctypes.pointer(self.instant)
        m.noise_per_step = sensors.noise_scales.size
        # recording: where each value goes in a row
        recorder = run.recorder
        self._f_lat_max = np.array(recorder.view("F_lat_max"))
        m.f_lat_max = native.dptr(self._f_lat_max)
        m.row_width = len(recorder.row)
        at = recorder.index
        runs = _runs([at(c) for c in io.output_columns])
        self._indices = [np.array(a, dtype=np.intc) for a in (
            runs, [at(c) for c in io.flag_columns], [at(c) for c in run.scalar_columns])]
        m.n_output_runs = len(runs)
        m.output_runs, m.flag_at, m.scalar_at = (a.ctypes.data_as(_I_PTR) for a in self._indices)
        for block in ("phi_meas", "F_lat_max"):
            first = at(f"{block}1")
            if [at(f"{block}{i}") for i in range(1, n + 1)] != list(range(first, first + n)):
                raise CosimError(f"the recorder's {block} columns are not side by side")
        m.at_phi_meas, m.at_f_lat_max = at("phi_meas1"), at("F_lat_max1")
        # goal
        goal = run.goal
        m.check_goal = int(bool(goal.check))
        m.goal_from = goal.t_end - 1e-12
        m.goal_x, m.goal_y, m.goal_theta = (float(a) for a in goal.pose)
        m.goal_position, m.goal_heading = goal.position, goal.heading
        m.goal_slack = self.goal_slack
        # scratch
        m.state = native.dptr(io.state)
        self._outputs = np.empty(len(io.output_names))
        m.outputs = native.dptr(self._outputs)
        self._flags = (c_int * (n + 1))()
        m.flags = ctypes.cast(self._flags, _I_PTR)
        # events: the times at which a push or slide starts or ends
        self.thresholds = run.events.switch_times()
        self._slide_refs = {i: slave.value_references([f"slide[{i}]"])[0]
                            for i in io.write_slide}

    # ------------------------------------------------------------------ the run
    def run(self, t0: float, step: float, n_steps: int, bar=None) -> tuple[str, str] | None:
        """Step from ``t0`` as ``PythonLoop.run`` does, with the same results bit for bit: the
        status and message of a jackknife or the goal, or None if the horizon ended first."""
        r, m, lib = self.run_, self.m, self.lib
        slave, events, sensors, recorder = r.slave, r.events, r.sensors, r.recorder
        m.t0, m.step, m.n_steps = t0, step, n_steps
        call = lib.pt_master_run
        ref = ctypes.byref(m)
        k = 0
        while True:
            t = t0 + k * step
            # the events due at t_k, as the Python loop applies them
            if events.biases:
                for bias in events.biases_due(t):
                    sensors.set_bias(bias.joint, bias.bias)
            self._keep = self._events_at(t)  # arrays the struct points to
            rows = recorder.free_rows()
            m.rows = native.dptr(rows)
            k_stop = min(n_steps + 1, k + CHUNK, k + len(rows))
            noise_state = self._draw_noise(sensors, k_stop - k)
            m.time = slave.time
            reason = call(ref, k, k_stop)
            done = m.k - k  # steps recorded and stepped
            recorded = done + (reason in (_HORIZON, _JACKKNIFE, _GOAL_CANDIDATE)
                               or (reason == _FMI_ERROR and m.failed_call == _DO_STEP))
            measured = done + (reason not in (_PAUSE, _ARGUMENT)
                               and not (reason == _FMI_ERROR and m.failed_call == _GET_STATE))
            recorder.advance(recorded)
            slave.time = m.time
            self.tracker.has_last = bool(sensors.config.measure_last_pose)
            if noise_state is not None and measured < k_stop - k:
                self._rewind_noise(sensors, noise_state, measured)
            if bar is not None and done:
                bar.update(done)
            t_k = t0 + m.k * step
            if reason == _PAUSE:
                k = m.k
            elif reason == _HORIZON:
                return None
            elif reason == _JACKKNIFE:
                return r.jackknife(t_k)
            elif reason == _GOAL_CANDIDATE:
                x_n, y_n, th_n = r.io.pose.tolist()[3:]
                reached = r.goal_reached(t_k, x_n, y_n, th_n)
                if reached is not None:
                    return reached
                if m.k == n_steps:
                    return None
                slave.do_step(t_k, step)
                if bar is not None:
                    bar.update(1)
                k = m.k + 1
            elif reason == _FMI_ERROR:
                raise self._fmi_error(t_k, step)
            elif reason == _CONTROL_ERROR:
                raise self._control_error(t_k)
            else:
                raise CosimError(f"the compiled step loop refused its arguments at step {m.k}")

    def _events_at(self, t: float):
        """Set the call's events from ``t`` [s] on: the slide writes due now, the active
        pushes, the next instant where an event is due. Returns the arrays the struct points
        to (keep them alive through the call)."""
        m, events = self.m, self.run_.events
        changes = events.slide_changes(t) if events.slides else []
        m.slide = events.slide_speed(self.run_.n) if events.slides else 0.0
        slide_vr = (c_uint * max(len(changes), 1))(*[self._slide_refs[i] for i, _ in changes])
        slide_values = np.array([speed for _, speed in changes] or [0.0])
        m.n_slide_writes = len(changes)
        m.slide_vr, m.slide_values = ctypes.cast(slide_vr, _U_PTR), native.dptr(slide_values)
        active = events.active_pushes(t)
        pushes = np.array([(p.fx, p.fy, p.lateral) for p in active] or [(0.0, 0.0, 0.0)],
                          dtype=float)
        self.instant.n_pushes = len(active)
        self.instant.pushes = native.dptr(pushes)
        m.pause_at = next((b for b in self.thresholds if b > t), math.inf)
        m.next_bias = events.next_bias_time
        self._changes = changes
        return slide_vr, slide_values, pushes

    def _draw_noise(self, sensors: Sensors, steps: int):
        """Draw the noise of ``steps`` steps (None without noise; else the generator's state
        before the draw)."""
        if not sensors.noise_scales.size:
            return None
        state = sensors.rng.bit_generator.state
        self._noise = sensors.draw_noise(steps)
        self.m.noise_values = native.dptr(self._noise)
        return state

    @staticmethod
    def _rewind_noise(sensors: Sensors, state, steps: int) -> None:
        """Leave the generator where the Python loop's sensors would after ``steps`` steps."""
        sensors.rng.bit_generator.state = state
        sensors.draw_noise(steps)

    def _fmi_error(self, t: float, step: float) -> CosimError:
        """The Python loop's error of the FMI call that failed at ``t``."""
        m, slave, io = self.m, self.run_.slave, self.run_.io
        call, status = m.failed_call, m.fmi_status
        if call == _GET_STATE:
            return slave.read_error(io.state_names, status)
        if call == _SET_INPUTS:
            return slave.write_error(io.input_names, tuple(m.inputs), status)
        if call == _SET_SLIDE:
            i, speed = self._changes[m.failed_slide]
            return slave.write_error([f"slide[{i}]"], (speed,), status)
        if call == _GET_OUTPUTS:
            return slave.read_error(io.output_names, status)
        if call == _GET_FLAGS:
            return slave.read_error(io.flag_names, status)
        return slave.step_error(t, step, status)

    def _control_error(self, t: float) -> Exception:
        """The exception of the control instant the C law refused at ``t`` (the tracker's own
        error for the measurement it was given)."""
        tracker = self.tracker
        k = tracker.instant
        row = self.run_.recorder.free_rows()[0]  # the refused step's row, not recorded
        phi = row[self.m.at_phi_meas:self.m.at_phi_meas + self.run_.n].tolist()
        last = (k.m.x_n, k.m.y_n, k.m.theta_n) if k.m.has_last else None
        measurement = Measurement(k.m.x0, k.m.y0, k.m.theta0, phi, last)
        sample = k.sample
        ref = ReferenceSample(sample.x, sample.y, sample.theta, sample.v, sample.w,
                              sample.direction)
        return tracker.error(self.m.control_status, t, measurement, ref)
