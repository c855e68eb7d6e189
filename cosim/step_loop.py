"""The master's step loop (``cosim/csrc/master_loop.c``): the one loop that steps every run.

One C call runs many communication steps (FMU reads and writes through the FMU's own functions,
FMI 2.0 or 3.0, the step's closed-loop work, the recorder's rows, the jackknife and goal tests,
the doStep) and returns to Python only where Python must act:

* at the top of a step where an event is due (a bias switch, a push or a slide starting or
  ending): Python applies it and the next call goes on;
* after a budget of steps (:data:`CHUNK`, or when the recorder's storage is full): the progress
  bar moves;
* at a goal candidate (the last trailer within the goal's tolerance up to 1e-9 relative): Python
  makes the exact test (``math.hypot``) and stops or steps on;
* at a jackknife, at the horizon's end, on a failed FMI call or a refused control instant.

The step's closed-loop work is the engine's ``pt_step`` (``core/csrc/step.c``: sensors,
reference sample, pull leader, command, push force, tracking errors) when the controller is the
compiled law tracking a line/arc reference (with the slip governor after it, in C, when the law
is governed) or an open-loop profile (its :class:`~pushtrain.core.openloop.Profile` table,
handed to C once and evaluated there each step; the reference sample's pose and the errors are
the NaN ``PT_NO_VALUE``). Only a law written in Python (the tests' readable law) or the compiled
law on a sampled reference is called back from the loop each step through a hook
(:class:`PythonLaw`: the compiled sensors, the Python command, the push force and errors in
Python); no bundled example takes that path.

Noise comes from the sensors' own ``numpy.random.Generator``: Python draws the standard normals
of a call's steps in one block (:class:`NoiseBuffer`), in the sensor model's order, scaled as
``Generator.normal`` does; the values a call did not use are the next call's first ones, so the
steps get the numbers a draw per step would give.
"""

from __future__ import annotations

import ctypes
import math
from ctypes import POINTER, c_double, c_int, c_long, c_uint, c_void_p
from importlib import resources

import numpy as np

from pushtrain.core import native
from pushtrain.core.controller import Tracker
from pushtrain.core.kinematics import wrap_scalar
from pushtrain.core.openloop import Profile
from pushtrain.core.reference import ReferenceSample
from pushtrain.core.sensors import Measurement, Sensors
from pushtrain.errors import ControllerError, CosimError, NativeBuildError

__all__ = ["CHUNK", "LOOP_FILES", "PythonLaw", "NoiseBuffer", "StepLoop"]

CHUNK = 1024
"""Most steps one call of the loop runs (then the progress bar moves)."""

LOOP_FILES = ("master_loop.c", "master_loop.h")
"""The co-simulation's own C, in ``cosim/csrc`` (compiled with the engine's files)."""

# reasons pt_master_run returns (master_loop.h PT_LOOP_*)
_PAUSE, _HORIZON, _JACKKNIFE, _GOAL_CANDIDATE, _FMI_ERROR, _CONTROL_ERROR, _ARGUMENT = range(7)
# failed FMI calls (PT_CALL_*)
_GET_STATE, _SET_INPUTS, _GET_OUTPUTS, _GET_FLAGS, _DO_STEP = 1, 2, 4, 5, 6
_OUT_COUNT = 13  # PT_OUT_COUNT: v_cmd, w_cmd, push_x, push_y, the sample (6), the errors (3)

_U_PTR, _D_PTR, _I_PTR = POINTER(c_uint), native.D_PTR, POINTER(c_int)
_HOOK = ctypes.CFUNCTYPE(c_int, c_void_p, c_double)


class PtFmuRead(ctypes.Structure):
    """``PtFmuRead`` of ``master_loop.h``."""

    _fields_ = [("vr", _U_PTR), ("nvr", c_int), ("count", c_int), ("index", _I_PTR),
                ("n_named", c_int), ("values", c_void_p)]


class PtMasterLoop(ctypes.Structure):
    """``PtMasterLoop`` of ``master_loop.h``."""

    _fields_ = [
        ("component", c_void_p), ("fmi_version", c_int), ("get_real", c_void_p),
        ("set_real", c_void_p), ("get_boolean", c_void_p), ("do_step", c_void_p),
        ("state", PtFmuRead), ("outputs", PtFmuRead), ("flags", PtFmuRead),
        ("input_vr", _U_PTR), ("n", c_int),
        ("t0", c_double), ("step", c_double), ("n_steps", c_long),
        ("engine", POINTER(native.PtStep)), ("noise_values", _D_PTR), ("noise_per_step", c_int),
        ("hook", _HOOK), ("hook_user", c_void_p), ("hook_out", _D_PTR), ("hook_phi", _D_PTR),
        ("rows", _D_PTR), ("row_width", c_int), ("output_at", _I_PTR), ("flag_at", _I_PTR),
        ("scalar_at", _I_PTR), ("at_phi_meas", c_int), ("at_f_lat_max", c_int),
        ("f_lat_max", _D_PTR), ("slide", c_double),
        ("check_goal", c_int), ("goal_from", c_double), ("goal_x", c_double),
        ("goal_y", c_double), ("goal_theta", c_double), ("goal_position", c_double),
        ("goal_heading", c_double), ("goal_slack", c_double),
        ("pause_at", c_double), ("next_bias", c_double),
        ("truth", _D_PTR),
        ("k", c_long), ("time", c_double), ("inputs", c_double * 4), ("failed_call", c_int),
        ("fmi_status", c_int), ("control_status", c_int),
    ]


def _library() -> ctypes.CDLL:
    """The co-simulation's own library: ``cosim/csrc/master_loop.c`` on the engine's files
    (:func:`pushtrain.core.native.engine_files`), built and cached like the engine's, the
    loop's prototypes declared (layout checked) when it is first loaded."""
    folder = resources.files("pushtrain.cosim") / "csrc"
    files = {**native.engine_files(), **{name: folder / name for name in LOOP_FILES}}
    return native.load_library("pushtrain_cosim", files, declare=_declare_loop)


def _declare_loop(lib: ctypes.CDLL, path) -> None:
    """Declare the step loop's prototypes and check its struct's size against the binding's."""
    lib.pt_master_loop_sizeof.restype, lib.pt_master_loop_sizeof.argtypes = ctypes.c_size_t, []
    lib.pt_master_run.restype = c_int
    lib.pt_master_run.argtypes = [POINTER(PtMasterLoop), c_long, c_long]
    size = lib.pt_master_loop_sizeof()
    if size != ctypes.sizeof(PtMasterLoop):
        raise NativeBuildError(f"PtMasterLoop is {size} bytes in {str(path)!r} but "
                               f"{ctypes.sizeof(PtMasterLoop)} in cosim/step_loop.py: the "
                               "binding does not match master_loop.h")


class NoiseBuffer:
    """The sensors' noise, drawn in blocks of steps: :meth:`take` gives the noise of the next
    ``steps`` measurements (the values left over by the last call first), :meth:`used` says how
    many of them a call used."""

    def __init__(self, sensors: Sensors):
        self.sensors = sensors
        self.width = sensors.noise_scales.size
        self.values = np.empty((0, self.width))

    def take(self, steps: int) -> np.ndarray:
        if len(self.values) < steps:
            more = self.sensors.draw_noise(steps - len(self.values))
            self.values = np.concatenate((self.values, more)) if len(self.values) else more
        return self.values

    def used(self, steps: int) -> None:
        self.values = self.values[steps:]


class PythonLaw:
    """The step's closed-loop work for a controller the engine does not run (a law written in
    Python, the compiled law on a sampled reference), called back from the C loop: the compiled
    sensors measure ``truth`` into ``phi``, the controller commands through
    ``command(t, measurement) -> (v0, w0, info, ref)``, and the push force and tracking errors
    are computed here. The results go to :attr:`out` (``PT_OUT_*`` order); an exception is kept
    in :attr:`error`."""

    def __init__(self, truth: np.ndarray, sensors: Sensors, events, command):
        self.truth, self.events, self.command = truth, events, command
        self.out = np.zeros(_OUT_COUNT)
        self.phi = np.zeros(sensors.n)
        self._measure = sensors.measurer(truth, self.phi)
        self.error: BaseException | None = None
        self.callback = _HOOK(self._call)  # kept alive with the object

    def step(self, t: float) -> tuple:
        """``(v_cmd, w_cmd, push_x, push_y, x_d, y_d, theta_d, v_d, w_d, direction, e_lon,
        e_lat, e_theta)`` at ``t`` [s] for the true state in ``truth``; the readings into
        ``phi``."""
        v_cmd, w_cmd, _, ref = self.command(t, self._measure())
        x_n, y_n, th_n = self.truth[3:6].tolist()
        push_x, push_y = self.events.push_force(t, th_n) if self.events.pushes else (0.0, 0.0)
        if math.isnan(ref.x):  # no reference: the one NaN, as pt_step's PT_NO_VALUE
            return (v_cmd, w_cmd, push_x, push_y, *ref, math.nan, math.nan, math.nan)
        dx, dy = x_n - ref.x, y_n - ref.y  # the last trailer's error in the reference frame
        c, s = math.cos(ref.theta), math.sin(ref.theta)
        return (v_cmd, w_cmd, push_x, push_y, *ref, c * dx + s * dy, -s * dx + c * dy,
                wrap_scalar(th_n - ref.theta))

    def _call(self, _user, t: float) -> int:
        try:
            self.out[:] = self.step(t)
        except BaseException as exc:  # noqa: BLE001 (handed back to the loop's caller)
            self.error = exc
            return 1
        return 0


def _intc(values) -> np.ndarray:
    return np.array(values, dtype=np.intc)


class StepLoop:
    """The step loop of one run.

    ``run`` (below) needs: ``slave`` (a started
    :class:`~pushtrain.cosim.fmu_slave.TrailerTrainSlave`), ``io`` (the names it moves:
    ``state_names``, ``input_names``, ``output_names``/``output_columns``,
    ``flag_names``/``flag_columns``, ``write_slide``), ``tracking`` (the run's
    :class:`~pushtrain.core.tracking.TrackingLoop`), ``sensors``, ``events``, ``recorder`` and
    ``ends`` (``goal``, ``goal_reached(t, x_n, y_n, th_n)``, ``jackknife(t)``)."""

    goal_slack = 1e-9
    """The C loop hands a step back as a goal candidate when the last trailer is within
    (1 + goal_slack) times the goal's tolerances; Python's own test (``math.hypot``) decides."""

    def __init__(self, slave, io, tracking, sensors: Sensors, events, recorder, ends,
                 scalar_columns):
        self.slave, self.io, self.sensors, self.events = slave, io, sensors, events
        self.recorder, self.ends, self.n = recorder, ends, sensors.n
        self.lib = _library()
        n = self.n
        m = self.m = PtMasterLoop()
        functions = slave.fmi_functions()
        m.component, m.fmi_version = functions["component"], slave.fmi_version
        m.get_real, m.set_real = functions["get_real"], functions["set_real"]
        m.get_boolean, m.do_step = functions["get_boolean"], functions["do_step"]
        self._keep: list = []  # arrays the struct points to
        self._read(m.state, io.state_names, c_double)
        self._read(m.outputs, io.output_names, c_double)
        self._read(m.flags, io.flag_names, c_int)
        refs, _, index = slave.read_plan(io.input_names)
        if index is not None or len(refs) != 4:
            raise CosimError(f"the FMU's inputs {io.input_names} are not four scalars")
        m.input_vr = self._pointer((c_uint * 4)(*refs), _U_PTR)
        m.n = n
        # the step's closed-loop work: the engine (the law's instant or an open-loop profile,
        # the run's own sensor model and memory, noise drawn per call, the pushes set per call)
        # or a law written in Python, called back
        self.tracker: Tracker | None = tracking.tracker
        profile = getattr(tracking.controller, "profile", None)
        self.profile = profile if self.tracker is None and isinstance(profile, Profile) else None
        self.truth = np.zeros(n + 6)
        m.truth = self._pointer(self.truth)
        self.law = None
        if self.tracker is not None or self.profile is not None:
            self.engine = native.PtStep(sensors=ctypes.pointer(sensors.model))
            if self.tracker is not None:
                self.tracker.has_last = bool(sensors.config.measure_last_pose)
                self.engine.track = ctypes.pointer(self.tracker.instant)
                governor = self.tracker.governor  # the slip governor, in C after the law
                if governor is not None:
                    governor.struct.dt = self.tracker.dt
                    self.engine.governor = ctypes.pointer(governor.struct)
                    self.engine.governor_work = self._pointer(governor.work)
            else:
                self.engine.profile = ctypes.pointer(self.profile.struct)
            m.engine = ctypes.pointer(self.engine)
            m.noise_per_step = sensors.noise_scales.size
            self.noise = NoiseBuffer(sensors) if m.noise_per_step else None
        else:
            self.law = PythonLaw(self.truth, sensors, events, tracking.command)
            m.hook = self.law.callback
            m.hook_out, m.hook_phi = self._pointer(self.law.out), self._pointer(self.law.phi)
            self.noise = None
        # recording: where each value goes in a row
        at = recorder.index
        self._f_lat_max = np.array(recorder.view("F_lat_max"))
        m.f_lat_max = self._pointer(self._f_lat_max)
        m.row_width = len(recorder.row)
        m.output_at = self._pointer(_intc([at(c) for c in io.output_columns]), _I_PTR)
        m.flag_at = self._pointer(_intc([at(c) for c in io.flag_columns]), _I_PTR)
        m.scalar_at = self._pointer(_intc([at(c) for c in scalar_columns]), _I_PTR)
        m.at_phi_meas, m.at_f_lat_max = (recorder.block_start(b) for b in ("phi_meas",
                                                                            "F_lat_max"))
        # goal
        goal = ends.goal
        m.check_goal = int(bool(goal.check))
        m.goal_from = goal.t_end - 1e-12
        m.goal_x, m.goal_y, m.goal_theta = (float(a) for a in goal.pose)
        m.goal_position, m.goal_heading = goal.position, goal.heading
        m.goal_slack = self.goal_slack
        # events: the times at which a push or slide starts or ends
        self.thresholds = events.switch_times()

    def _pointer(self, array, kind=_D_PTR):
        self._keep.append(array)
        if isinstance(array, np.ndarray):
            return array.ctypes.data_as(kind)
        return ctypes.cast(array, kind)

    def _read(self, read: PtFmuRead, names, value_type) -> None:
        """Fill ``read`` with how one call reads ``names``."""
        refs, count, index = self.slave.read_plan(names)
        read.vr = self._pointer((c_uint * len(refs))(*refs), _U_PTR)
        read.nvr, read.count, read.n_named = len(refs), count, len(names)
        read.index = None if index is None else self._pointer(_intc(index), _I_PTR)
        values = (value_type * count)()
        self._keep.append(values)
        read.values = ctypes.cast(values, c_void_p)

    # ------------------------------------------------------------------ the run
    def run(self, t0: float, step: float, n_steps: int, bar=None) -> tuple[str, str] | None:
        """Step from ``t0`` (communication points t0 + k step, k = 0..n_steps): the status and
        message of a jackknife or the goal, or None if the horizon ended first."""
        m, lib, slave, recorder = self.m, self.lib, self.slave, self.recorder
        m.t0, m.step, m.n_steps = t0, step, n_steps
        call, ref = lib.pt_master_run, ctypes.byref(m)
        k = 0
        while True:
            t = t0 + k * step
            self._events_at(t)
            rows = recorder.free_rows()
            m.rows = native.dptr(rows)
            k_stop = min(n_steps + 1, k + CHUNK, k + len(rows))
            if self.noise is not None:
                noise = self.noise.take(k_stop - k)
                m.noise_values = native.dptr(noise)
            m.time = slave.time
            reason = call(ref, k, k_stop)
            done = m.k - k  # steps recorded and stepped
            recorded = done + (reason in (_HORIZON, _JACKKNIFE, _GOAL_CANDIDATE)
                               or (reason == _FMI_ERROR and m.failed_call == _DO_STEP))
            measured = done + (reason not in (_PAUSE, _ARGUMENT)
                               and not (reason == _FMI_ERROR and m.failed_call == _GET_STATE))
            recorder.advance(recorded)
            slave.time = m.time
            if self.tracker is not None:
                self.tracker.has_last = bool(self.sensors.config.measure_last_pose)
            if self.noise is not None:
                self.noise.used(measured)
            if bar is not None and done:
                bar.update(done)
            t_k = t0 + m.k * step
            if reason == _PAUSE:
                k = m.k
            elif reason == _HORIZON:
                return None
            elif reason == _JACKKNIFE:
                return self.ends.jackknife(t_k)
            elif reason == _GOAL_CANDIDATE:
                x_n, y_n, th_n = self.truth[3:6].tolist()
                reached = self.ends.goal_reached(t_k, x_n, y_n, th_n)
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
                raise CosimError(f"the step loop refused its arguments at step {m.k}")

    def _events_at(self, t: float) -> None:
        """Apply the events due at ``t`` [s] (bias switches, slide speeds that change) and set
        the call's: the active pushes, the last trailer's slide speed, the next instant where an
        event is due."""
        m, events = self.m, self.events
        if events.biases:
            for bias in events.biases_due(t):
                self.sensors.set_bias(bias.joint, bias.bias)
        if events.slides:
            for i, speed in events.slide_changes(t):
                self.io.write_slide[i]((speed,))
            m.slide = events.slide_speed(self.n)
        if self.law is None:
            active = events.active_pushes(t)
            self._pushes = np.array([(p.fx, p.fy, p.lateral) for p in active] or [(0.0,) * 3],
                                    dtype=float)
            self.engine.n_pushes = len(active)
            self.engine.pushes = native.dptr(self._pushes)
        m.pause_at = next((b for b in self.thresholds if b > t), math.inf)
        m.next_bias = events.next_bias_time

    def _fmi_error(self, t: float, step: float) -> CosimError:
        """The error of the FMI call that failed at ``t``."""
        m, slave, io = self.m, self.slave, self.io
        call, status = m.failed_call, m.fmi_status
        if call == _GET_STATE:
            return slave.read_error(io.state_names, status)
        if call == _SET_INPUTS:
            return slave.write_error(io.input_names, tuple(m.inputs), status)
        if call == _GET_OUTPUTS:
            return slave.read_error(io.output_names, status)
        if call == _GET_FLAGS:
            return slave.read_error(io.flag_names, status)
        return slave.step_error(t, step, status)

    def _control_error(self, t: float) -> BaseException:
        """The exception of the control instant refused at ``t``: the Python law's own, the
        open-loop profile's, or the compiled tracker's error for the measurement it was
        given."""
        if self.law is not None:
            error, self.law.error = self.law.error, None
            return error
        if self.profile is not None:
            status = self.m.control_status
            return ControllerError(f"the open-loop profile refused t = {t!r} s: "
                                   f"{native.STATUS.get(status, status)}")
        tracker = self.tracker
        k = tracker.instant
        row = self.recorder.free_rows()[0]  # the refused step's row, not recorded
        at = self.m.at_phi_meas
        phi = row[at:at + self.n].tolist()
        last = (k.m.x_n, k.m.y_n, k.m.theta_n) if k.m.has_last else None
        measurement = Measurement(k.m.x0, k.m.y0, k.m.theta0, phi, last)
        sample = k.sample
        ref = ReferenceSample(sample.x, sample.y, sample.theta, sample.v, sample.w,
                              sample.direction)
        return tracker.error(self.m.control_status, t, measurement, ref)
