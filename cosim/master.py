"""Co-simulation master: the TrailerTrain FMU stepped with the backward controller in the loop.

Each communication step ``t_k = t0 + k h`` (default h = 0.005 s, the paper's sampling time):
read the FMU's outputs -> sensors (bias, noise, quantization, backlash) -> controller (Kanayama +
inverse chain kinematics) -> set the FMU's inputs -> ``fmi2DoStep``. Scheduled events apply a
push force on the last trailer, an imposed lateral slide of a trailer (a kinematic disturbance,
the paper's Fig. 9(b) in the rolling model) or switch a joint-angle bias on. A recorder keeps every
output, input, reference and error as a numpy structured array.

Use :func:`simulate`; it returns a :class:`Result` that can :meth:`~Result.save` CSV, NPZ and
``summary.json`` (each written atomically).
"""

from __future__ import annotations

import json
import logging
import math
import sys
import time as _time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from pushtrain.core.controller import BackwardController, ControllerConfig, ControllerError
from pushtrain.core.kinematics import ChainGeometry, body_positions_from_last, wrap_scalar
from pushtrain.core.reference import Reference
from pushtrain.core.tracking import TrackingLoop
from pushtrain.files import atomic_write

from .fmu_slave import CosimError, CosimInputError, TrailerTrainSlave
from .sensors import SensorConfig, Sensors

__all__ = [
    "CosimError",
    "PlantConfig",
    "InitialState",
    "Push",
    "Slide",
    "SetBias",
    "Result",
    "simulate",
    "STATUS_GOAL",
    "STATUS_NOT_REACHED",
    "STATUS_JACKKNIFE",
    "STATUS_FMU_ERROR",
    "STATUS_TIME_LIMIT",
]

log = logging.getLogger(__name__)

STATUS_GOAL = "goal_reached"
STATUS_NOT_REACHED = "goal_not_reached"
STATUS_JACKKNIFE = "jackknifed"
STATUS_FMU_ERROR = "fmu_error"
STATUS_TIME_LIMIT = "time_limit"
STATUS_COMPLETED = "completed"  # fixed-horizon run without a goal check


def _positive(name: str, value, allow_zero=False) -> float:
    ok = isinstance(value, (int, float)) and math.isfinite(value)
    ok = ok and (value >= 0 if allow_zero else value > 0)
    if not ok:
        raise CosimInputError(f"{name} = {value!r}: must be a finite number {'>= 0' if allow_zero else '> 0'}")
    return float(value)


@dataclass
class PlantConfig:
    """Parameters of the TrailerTrain FMU (names as in the FMU; arrays per trailer i = 1..n).

    ``None`` keeps the FMU's default (Table 1 of the paper). ``front`` holds F_1..F_n, ``rear``
    R_0..R_{n-1} [m]; ``mass``, ``payload`` [kg], ``inertia`` [kg m^2], ``mu`` [-] per trailer.
    """

    n_trailers: int
    front: Sequence[float] | float | None = None
    rear: Sequence[float] | float | None = None
    mass: Sequence[float] | float | None = None
    inertia: Sequence[float] | float | None = None
    payload: Sequence[float] | float | None = None
    mu: Sequence[float] | float | None = None
    g: float | None = None
    robot_tau: float | None = None
    robot_acc_max: float | None = None
    robot_alpha_max: float | None = None
    phi_max: float | None = None
    slip_mode: int | None = None
    max_substep: float | None = None
    slip_substep: float | None = None

    def _array(self, name: str, first: int):
        value = getattr(self, name)
        if value is None:
            return None
        arr = np.broadcast_to(np.asarray(value, dtype=float), (self.n_trailers,))
        return {f"{name}[{first + k}]": float(arr[k]) for k in range(self.n_trailers)}

    def geometry(self) -> ChainGeometry:
        """The plant's true hitch geometry (defaults 0.52 m)."""
        n = self.n_trailers
        front = np.broadcast_to(np.asarray(0.52 if self.front is None else self.front, float), (n,))
        rear = np.broadcast_to(np.asarray(0.52 if self.rear is None else self.rear, float), (n,))
        return ChainGeometry(front.copy(), rear.copy())

    def start_values(self) -> dict:
        """FMU start values for the parameters that are set."""
        out = {}
        for name, first in (("front", 1), ("rear", 0), ("mass", 1), ("inertia", 1),
                            ("payload", 1), ("mu", 1)):
            values = self._array(name, first)
            if values:
                out.update(values)
        for name in ("g", "robot_tau", "robot_acc_max", "robot_alpha_max", "phi_max",
                     "slip_mode", "max_substep", "slip_substep"):
            value = getattr(self, name)
            if value is not None:
                out[name] = value
        return out


@dataclass
class InitialState:
    """Initial configuration: robot pose, all headings and robot velocities.

    Build it with :meth:`behind_reference` to place the train on the reference's start.
    """

    x0: float
    y0: float
    theta: np.ndarray  # (n+1,) [rad]
    v0: float = 0.0
    w0: float = 0.0

    @classmethod
    def behind_reference(
        cls,
        reference: Reference,
        geometry: ChainGeometry,
        lateral_offset: float = 0.0,
        heading_offset: float = 0.0,
        joint_angles: Sequence[float] | None = None,
    ) -> "InitialState":
        """A train whose last trailer starts at the reference's start pose.

        ``lateral_offset`` [m] moves the last trailer along the reference heading's left normal,
        ``heading_offset`` [rad] turns it; ``joint_angles`` (n,) [rad] bend the chain (default
        straight).
        """
        x, y, th = (float(a) for a in reference.start)
        th_n = th + heading_offset
        x += -math.sin(th) * lateral_offset
        y += math.cos(th) * lateral_offset
        n = geometry.n
        phi = np.zeros(n) if joint_angles is None else np.asarray(joint_angles, dtype=float)
        if phi.shape != (n,):
            raise CosimInputError(f"joint_angles has shape {phi.shape}; expected ({n},)")
        # theta_{i-1} = theta_i + phi_i, from the last trailer forward
        theta = th_n + np.concatenate((np.cumsum(phi[::-1])[::-1], [0.0]))
        xs, ys = body_positions_from_last(x, y, theta, geometry)
        return cls(float(xs[0]), float(ys[0]), theta)

    def start_values(self) -> dict:
        out = {"x0_start": self.x0, "y0_start": self.y0, "v_start": self.v0, "w_start": self.w0}
        out.update({f"theta_start[{i}]": float(a) for i, a in enumerate(self.theta)})
        return out


@dataclass(frozen=True)
class Push:
    """External force on the last trailer's axle midpoint from ``t`` for ``duration`` [s].

    ``lateral`` [N] acts along the last trailer's left normal at the push's start (positive: to
    its left as seen facing the robot); ``fx``, ``fy`` [N] add a world-frame force. In the rolling
    model (slip_mode 0) a push changes the wheel and hitch forces only.
    """

    t: float
    duration: float
    lateral: float = 0.0
    fx: float = 0.0
    fy: float = 0.0


@dataclass(frozen=True)
class Slide:
    """Imposed lateral slide of trailer ``trailer``'s wheel: ``distance`` [m] along its left
    normal over ``duration`` [s] from ``t`` (a kinematic disturbance: the paper's hand push,
    Fig. 9(b), in the rolling model). ``trailer`` None means the last trailer."""

    t: float
    duration: float
    distance: float
    trailer: int | None = None


@dataclass(frozen=True)
class SetBias:
    """Switch the measurement bias of joint ``joint`` (1..n) to ``bias`` [rad] at ``t``."""

    t: float
    joint: int
    bias: float


@dataclass
class Result:
    """Outcome of :func:`simulate`."""

    status: str
    message: str
    data: np.ndarray  # structured array, one row per communication point
    summary: dict
    n_trailers: int
    fmu_log: str = ""
    files: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status in (STATUS_GOAL, STATUS_COMPLETED)

    def save(self, out_dir) -> dict:
        """Write ``results.csv``, ``results.npz`` and ``summary.json`` into ``out_dir``."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        names = self.data.dtype.names
        csv_path = out / "results.csv"
        _atomic_write(csv_path, lambda f: _write_csv(f, self.data), binary=False)
        npz_path = out / "results.npz"
        _atomic_write(npz_path, lambda f: np.savez_compressed(f, **{k: self.data[k] for k in names}))
        summary_path = out / "summary.json"
        _atomic_write(summary_path, lambda f: json.dump(self.summary, f, indent=2), binary=False)
        self.files = {"csv": str(csv_path), "npz": str(npz_path), "summary": str(summary_path)}
        return self.files


def _write_csv(f, data: np.ndarray) -> None:
    names = data.dtype.names
    f.write(",".join(names) + "\n")
    columns = np.column_stack([data[k].astype(float) for k in names])
    np.savetxt(f, columns, delimiter=",", fmt="%.10g")


def _atomic_write(path: Path, writer, binary: bool = True) -> None:
    """``writer(f)`` on an open file, written atomically over ``path``."""
    def write(partial: Path) -> None:
        with open(partial, "wb" if binary else "w") as f:
            writer(f)

    atomic_write(path, write)


def _columns(n: int) -> list[str]:
    cols = ["t"]
    for base in ("x", "y", "theta", "v", "w"):
        cols += [f"{base}{i}" for i in range(n + 1)]
    for base in ("phi", "phi_meas", "F_lat", "F_lat_max", "slipping", "u"):
        cols += [f"{base}{i}" for i in range(1, n + 1)]
    cols += ["v_cmd", "w_cmd", "push_x", "push_y", "slide"]
    cols += ["x_d", "y_d", "theta_d", "v_d", "w_d", "direction"]
    cols += ["e_lon", "e_lat", "e_theta", "jackknifed"]
    return cols


def _validate_events(events, n: int, t_end: float):
    pushes, slides, biases = [], [], []
    for k, ev in enumerate(events):
        where = f"events[{k}]"
        if isinstance(ev, Push):
            _positive(f"{where}.duration", ev.duration)
            pushes.append(ev)
        elif isinstance(ev, Slide):
            _positive(f"{where}.duration", ev.duration)
            trailer = n if ev.trailer is None else ev.trailer
            if not (isinstance(trailer, int) and 1 <= trailer <= n):
                raise CosimInputError(f"{where}.trailer = {ev.trailer!r}: allowed are 1..{n}")
            slides.append(ev)
        elif isinstance(ev, SetBias):
            if not (isinstance(ev.joint, int) and 1 <= ev.joint <= n):
                raise CosimInputError(f"{where}.joint = {ev.joint!r}: allowed are 1..{n}")
            biases.append(ev)
        else:
            raise CosimInputError(f"{where} = {ev!r}: allowed are Push, Slide and SetBias events")
        if not (isinstance(ev.t, (int, float)) and math.isfinite(ev.t) and ev.t >= 0):
            raise CosimInputError(f"{where}.t = {ev.t!r} s: must be finite and >= 0")
        if ev.t > t_end:
            log.warning("%s at t = %.3f s is after the end of the run (%.3f s)", where, ev.t, t_end)
    return pushes, slides, sorted(biases, key=lambda e: e.t)


def _steps(horizon: float, step: float) -> int:
    ratio = horizon / step
    k = round(ratio)
    if abs(ratio - k) > 1e-9 * max(1.0, ratio) or k < 1:
        raise CosimInputError(
            f"step = {step!r} s does not divide the horizon {horizon!r} s into whole steps "
            f"(ratio {ratio:.9g}); choose a step that divides it"
        )
    return int(k)


def simulate(
    fmu,
    reference: Reference,
    controller: ControllerConfig | BackwardController,
    sensors: SensorConfig | Sensors | None = None,
    events: Sequence = (),
    *,
    plant: PlantConfig | None = None,
    initial: InitialState | None = None,
    step: float = 0.005,
    horizon: float | None = None,
    settle_time: float = 20.0,
    goal_tolerance: tuple[float, float] = (0.05, math.radians(5.0)),
    check_goal: bool = True,
    progress: bool | None = None,
    out_dir=None,
) -> Result:
    """Co-simulate the FMU with the backward controller tracking ``reference``.

    Parameters
    ----------
    fmu : path-like
        A TrailerTrain ``.fmu`` (see :func:`pushtrain.fmu.build_fmu`).
    reference : Reference or SampledReference
        The last trailer's reference.
    controller : ControllerConfig or BackwardController
        Gains, limits and the controller's own chain model.
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
        number of steps.
    goal_tolerance : (float, float)
        Position [m] and heading [rad] tolerance on the last trailer at the goal.
    check_goal : bool
        Stop with ``goal_reached`` once the reference has ended and the last trailer is within
        tolerance; if False, run the whole horizon (status ``completed``).
    progress : bool or None
        Show a progress bar; None: only when stderr is a terminal and the run is long.
    out_dir : path-like, optional
        Save the results there (also when the run ends in an error status).

    Raises
    ------
    CosimError
        Bad configuration, detected before any stepping (the FMU's own errors during a run end
        the run with status ``fmu_error`` instead).
    """
    step = _positive("step", step)
    settle_time = _positive("settle_time", settle_time, allow_zero=True)
    if reference is None:
        if horizon is None or initial is None:
            raise CosimInputError("a run without a reference (open loop) needs a horizon and an initial state")
        check_goal = False
    elif not (hasattr(reference, "sample_at") and hasattr(reference, "t_end")):
        raise CosimInputError(f"reference = {reference!r}: need a Reference or SampledReference")
    t0 = float(getattr(reference, "t0", 0.0))
    if horizon is None:
        horizon = float(reference.t_end) - t0 + settle_time
        horizon = step * math.ceil(horizon / step - 1e-9)
    horizon = _positive("horizon", horizon)
    n_steps = _steps(horizon, step)
    pos_tol = _positive("goal_tolerance[0]", goal_tolerance[0])
    head_tol = _positive("goal_tolerance[1]", goal_tolerance[1])

    if isinstance(controller, ControllerConfig):
        ctrl = BackwardController(controller)
    elif hasattr(controller, "command") and hasattr(controller, "n"):
        ctrl = controller  # BackwardController or an open-loop command profile
    else:
        raise CosimInputError(f"controller = {controller!r}: need a ControllerConfig or BackwardController")
    n = ctrl.n
    sens = sensors if isinstance(sensors, Sensors) else Sensors(sensors or SensorConfig(n_joints=n))
    if sens.n != n:
        raise CosimInputError(f"sensors measure {sens.n} joints; the controller's chain has {n}")
    plant = plant or PlantConfig(n_trailers=n)
    if plant.n_trailers != n:
        raise CosimInputError(f"plant.n_trailers = {plant.n_trailers}; the controller's chain has {n}")
    pushes, slides, biases = _validate_events(events, n, t0 + horizon)
    if slides and plant.slip_mode == 1:
        raise CosimInputError("Slide events impose a kinematic slide (slip_mode 0); with "
                         "slip_mode = 1 the wheels slide physically: use Push events instead")
    if initial is None:
        initial = InitialState.behind_reference(reference, plant.geometry())
    if len(initial.theta) != n + 1:
        raise CosimInputError(f"initial.theta has {len(initial.theta)} headings; need n + 1 = {n + 1}")

    if hasattr(ctrl, "reset"):
        # rate limits start from the robot's initial velocity one step before t0
        ctrl.reset(initial.v0, initial.w0, t0 - step)
    times = t0 + step * np.arange(n_steps + 1)
    if reference is None:
        goal, t_ref_end = np.full(3, np.nan), math.inf
    else:
        goal = np.asarray(reference.goal, dtype=float)
        t_ref_end = float(reference.t_end)
    loop = TrackingLoop(ctrl, reference)

    slave = TrailerTrainSlave(fmu)
    if slave.n != n:
        slave.close()
        raise CosimInputError(f"the FMU {Path(fmu).name} has n = {slave.n} trailers; the controller's chain has {n}")
    cols = _columns(n)
    rec = np.full((n_steps + 1, len(cols)), np.nan)
    status, message = STATUS_TIME_LIMIT, ""
    wall_start = _time.perf_counter()
    k_last = -1
    bar = None
    try:
        start_values = plant.start_values()
        start_values.update(initial.start_values())
        slave.start(start_values, t0)
        out_names = (slave.names("x", 0, n) + slave.names("y", 0, n) + slave.names("theta", 0, n)
                     + slave.names("v", 0, n) + slave.names("w", 0, n) + slave.names("phi", 1, n)
                     + slave.names("F_lat", 1, n) + slave.names("slide_speed", 1, n))
        read = slave.real_reader(out_names)
        f_max = slave.get_reals(slave.names("F_lat_max", 1, n))
        slip_names = slave.names("slipping", 1, n) + ["jackknifed"]
        read_flags = slave.bool_reader(slip_names)
        write_cmd = slave.real_writer(["v_cmd", "w_cmd", "push_x", "push_y"])
        slide_writers = {i: slave.real_writer([f"slide[{i}]"]) for i in range(1, n + 1)}
        i_phi, i_flat = 5 * (n + 1), 5 * (n + 1) + n

        show = progress if progress is not None else (sys.stderr.isatty() and n_steps > 200)
        if show:
            from tqdm import tqdm

            bar = tqdm(total=n_steps, unit="step", desc="co-simulating", mininterval=0.5,
                       file=sys.stderr)
        bias_idx = 0
        slide_active = {}
        measure_last = bool(getattr(sens.config, "measure_last_pose", False))
        for k in range(n_steps + 1):
            t = float(times[k])
            while bias_idx < len(biases) and biases[bias_idx].t <= t + 1e-12:
                sens.set_bias(biases[bias_idx].joint, biases[bias_idx].bias)
                bias_idx += 1
            y = read()
            th_n = y[3 * (n + 1) - 1]
            x0, y0, th0 = y[0], y[n + 1], y[2 * (n + 1)]
            phi = y[i_phi:i_phi + n]
            if measure_last:
                meas = sens.measure(x0, y0, th0, phi, (y[n], y[2 * (n + 1) - 1], th_n))
            else:
                meas = sens.measure(x0, y0, th0, phi)
            v_cmd, w_cmd, _, ref = loop.command(t, meas)
            push_x = push_y = 0.0
            for p in pushes:
                if p.t - 1e-12 <= t < p.t + p.duration - 1e-12:
                    push_x += p.fx - math.sin(th_n) * p.lateral
                    push_y += p.fy + math.cos(th_n) * p.lateral
            write_cmd((v_cmd, w_cmd, push_x, push_y))
            if slides:
                speeds = dict.fromkeys(slide_active, 0.0)
                for ev in slides:
                    if ev.t - 1e-12 <= t < ev.t + ev.duration - 1e-12:
                        i = n if ev.trailer is None else ev.trailer
                        speeds[i] = speeds.get(i, 0.0) + ev.distance / ev.duration
                for i, speed in speeds.items():
                    if slide_active.get(i, 0.0) != speed:
                        slide_writers[i]((speed,))
                        slide_active[i] = speed
            slide_n = slide_active.get(n, 0.0)
            # outputs again: forces depend directly on the inputs just set
            y = read()
            flags = read_flags()
            # tracking error of the last trailer in the reference's (chain) frame
            dx, dy = y[n] - ref.x, y[2 * (n + 1) - 1] - ref.y
            c, s_ = math.cos(ref.theta), math.sin(ref.theta)
            row = rec[k]
            row[0] = t
            row[1:1 + 5 * (n + 1)] = y[:5 * (n + 1)]
            base = 1 + 5 * (n + 1)
            row[base:base + n] = y[i_phi:i_phi + n]
            row[base + n:base + 2 * n] = meas.phi
            row[base + 2 * n:base + 3 * n] = y[i_flat:i_flat + n]
            row[base + 3 * n:base + 4 * n] = f_max
            row[base + 4 * n:base + 5 * n] = flags[:n]
            row[base + 5 * n:base + 6 * n] = y[i_flat + n:i_flat + 2 * n]
            base += 6 * n
            row[base:base + 5] = (v_cmd, w_cmd, push_x, push_y, slide_n)
            row[base + 5:base + 11] = ref
            e_theta = wrap_scalar(y[3 * (n + 1) - 1] - ref.theta)
            row[base + 11:base + 15] = (c * dx + s_ * dy, -s_ * dx + c * dy, e_theta, flags[n])
            k_last = k
            if flags[n]:
                status = STATUS_JACKKNIFE
                worst = int(np.argmax(np.abs(y[i_phi:i_phi + n]))) + 1
                message = (f"jackknife at t = {t:.3f} s: |phi[{worst}]| = "
                           f"{math.degrees(abs(y[i_phi + worst - 1])):.1f} deg exceeds phi_max")
                break
            if check_goal and t >= t_ref_end - 1e-12:
                dist = math.hypot(y[n] - goal[0], y[2 * (n + 1) - 1] - goal[1])
                if dist <= pos_tol and abs(wrap_scalar(y[3 * (n + 1) - 1] - goal[2])) <= head_tol:
                    status = STATUS_GOAL
                    message = f"goal reached at t = {t:.3f} s ({dist * 100:.1f} cm from the goal)"
                    break
            if k == n_steps:
                break
            slave.do_step(t, step)
            if bar is not None and k % 200 == 0:
                bar.update(200 if k else 0)
        if status == STATUS_TIME_LIMIT:
            if not check_goal:
                status, message = STATUS_COMPLETED, f"ran the full horizon of {horizon:.3f} s"
            elif times[k_last] >= t_ref_end:
                status = STATUS_NOT_REACHED
                dist = math.hypot(rec[k_last, 1 + n] - goal[0], rec[k_last, 1 + 2 * (n + 1) - 1] - goal[1])
                message = (f"the reference ended at t = {t_ref_end:.3f} s but the last trailer was "
                           f"still {dist * 100:.1f} cm from the goal at t = {times[k_last]:.3f} s "
                           f"(tolerance {pos_tol * 100:.1f} cm, {math.degrees(head_tol):.1f} deg)")
            else:
                message = (f"time limit {horizon:.3f} s reached before the reference ended "
                           f"({t_ref_end:.3f} s)")
    except CosimError as exc:
        status, message = STATUS_FMU_ERROR, str(exc)
        log.error("%s", message)
    except ControllerError as exc:
        status, message = STATUS_FMU_ERROR, f"controller failed: {exc}"
        log.error("%s", message)
    finally:
        if bar is not None:
            bar.close()
        fmu_log = slave.last_messages()
        slave.close()
    wall = _time.perf_counter() - wall_start

    data_rows = rec[: k_last + 1]
    dtype = [(name, "f8") for name in cols]
    data = np.empty(len(data_rows), dtype=dtype)
    for j, name in enumerate(cols):
        data[name] = data_rows[:, j]
    summary = _summarize(data, n, status, message, wall, step, f_max if k_last >= 0 else None)
    result = Result(status, message, data, summary, n, fmu_log)
    log.info("co-simulation %s: %s (%d steps, %.2f s wall)", status, message, len(data) - 1, wall)
    if out_dir is not None:
        result.save(out_dir)
    return result


def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a**2))) if a.size else float("nan")


def _summarize(data, n, status, message, wall, step, f_max) -> dict:
    summary = {"status": status, "message": message, "n_trailers": n, "step": step,
               "steps": max(len(data) - 1, 0), "wall_time_s": round(wall, 4)}
    if len(data) == 0:
        return summary
    e_lat, e_th = data["e_lat"], data["e_theta"]
    summary.update(
        t_final=float(data["t"][-1]),
        lateral_error_m={"rms": _rms(e_lat), "max": float(np.max(np.abs(e_lat))),
                         "final": float(e_lat[-1])},
        heading_error_rad={"rms": _rms(e_th), "max": float(np.max(np.abs(e_th))),
                           "final": float(e_th[-1])},
        longitudinal_error_m={"rms": _rms(data["e_lon"]), "final": float(data["e_lon"][-1])},
        max_abs_phi_deg=[float(np.degrees(np.max(np.abs(data[f"phi{i}"])))) for i in range(1, n + 1)],
        steps_per_second=round((len(data) - 1) / wall, 1) if wall > 0 else None,
    )
    ratios, slips = [], []
    for i in range(1, n + 1):
        f = np.abs(data[f"F_lat{i}"])
        ratios.append(float(np.max(f) / data[f"F_lat_max{i}"][0]) if data[f"F_lat_max{i}"][0] > 0 else None)
        flag = data[f"slipping{i}"] > 0.5
        rising = np.flatnonzero(flag[1:] & ~flag[:-1]) + 1
        starts = ([0] if flag[0] else []) + rising.tolist()
        slips.append({"trailer": i, "events": len(starts),
                      "first_t": float(data["t"][starts[0]]) if starts else None,
                      "time_slipping_s": float(np.count_nonzero(flag) * step)})
    summary["max_F_lat_ratio"] = ratios
    summary["slip"] = slips
    return summary
