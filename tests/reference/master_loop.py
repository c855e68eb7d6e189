"""The co-simulation master's loop written step by step in Python: the reference the one step
loop (``cosim/csrc/master_loop.c`` through :mod:`pushtrain.cosim.step_loop`) is held equal to,
bit for bit (``tests/cosim/test_master_loop.py``).

At each communication point ``t_k = t0 + k step``: the bias switches due, the FMU's measured
states, the sensors (the compiled model, :meth:`Sensors.measurer`, one noise draw per step), the
controller through :class:`~pushtrain.core.tracking.TrackingLoop` (reference sample, pull guide,
command), the push force (:meth:`EventSchedule.push_force`) and the last trailer's tracking
errors (without a reference, an open loop, the NaN of ``math.nan``: a NaN computed from the
sample's NaN pose takes its sign from whichever operand the float operation returns, and
CPython 3.11 changes that once it specializes the expression), the FMU's inputs, the slide
speeds that change, every output and flag into the row, the jackknife and goal tests, the
doStep. SI units, radians.
"""

from __future__ import annotations

import math

import numpy as np

from pushtrain.core.controller import Controller, ControllerConfig
from pushtrain.core.kinematics import wrap_scalar
from pushtrain.core.sensors import SensorConfig, Sensors
from pushtrain.core.tracking import TrackingLoop
from pushtrain.cosim.events import EventSchedule
from pushtrain.cosim.fmu_slave import TrailerTrainSlave
from pushtrain.cosim.plant import InitialState, PlantConfig
from pushtrain.defaults import GOAL_TOLERANCE, SETTLE_TIME
from pushtrain.errors import ControllerError, CosimError
from pushtrain.table1 import SAMPLING_TIME


def columns(n: int) -> list[str]:
    """The result's columns in order."""
    cols = ["t"]
    for base in ("x", "y", "theta", "v", "w"):
        cols += [f"{base}{i}" for i in range(n + 1)]
    for base in ("phi", "phi_meas", "F_lat", "F_lat_max", "slipping", "u"):
        cols += [f"{base}{i}" for i in range(1, n + 1)]
    cols += ["v_cmd", "w_cmd", "push_x", "push_y", "slide"]
    cols += ["x_d", "y_d", "theta_d", "v_d", "w_d", "direction"]
    cols += ["e_lon", "e_lat", "e_theta", "jackknifed"]
    return cols


def run(fmu, reference, controller, sensors=None, events=(), *, plant=None, initial=None,
        step=SAMPLING_TIME, horizon=None, settle_time=SETTLE_TIME,
        goal_tolerance=GOAL_TOLERANCE, check_goal=True):
    """``(status, message, data)`` of a run as :func:`pushtrain.cosim.master.simulate` makes it
    (the same arguments; ``data`` a structured array of :func:`columns`)."""
    ctrl = Controller(controller) if isinstance(controller, ControllerConfig) else controller
    n = ctrl.n
    sens = sensors if isinstance(sensors, Sensors) else Sensors(sensors or SensorConfig(n))
    plant = plant or PlantConfig(n_trailers=n)
    t0 = float(getattr(reference, "t0", 0.0))
    if horizon is None:
        horizon = step * math.ceil((float(reference.t_end) - t0 + settle_time) / step - 1e-9)
    n_steps = round(horizon / step)
    if initial is None:
        initial = InitialState.behind_reference(reference, plant.geometry())
    if hasattr(ctrl, "reset"):
        ctrl.reset(initial.v0, initial.w0, t0 - step)
    loop = TrackingLoop(ctrl, reference, info=False)
    schedule = EventSchedule(events, n, t0 + horizon)
    goal = None if reference is None or not check_goal else np.asarray(reference.goal)
    t_end = math.inf if reference is None else float(reference.t_end)

    slave = TrailerTrainSlave(fmu, n_trailers=n)
    names = lambda base, first: slave.names(base, first, n)  # noqa: E731
    state_names = ["x[0]", "y[0]", "theta[0]", f"x[{n}]", f"y[{n}]", f"theta[{n}]",
                   *names("phi", 1)]
    output_names = [*names("x", 0), *names("y", 0), *names("theta", 0), *names("v", 0),
                    *names("w", 0), *names("phi", 1), *names("F_lat", 1),
                    *names("slide_speed", 1)]
    flag_names = [*names("slipping", 1), "jackknifed"]
    rows = []
    status = message = None
    try:
        slave.start({**plant.start_values(), **initial.start_values()}, t0)
        f_lat_max = slave.get_reals(names("F_lat_max", 1)).tolist()
        read_state = slave.real_reader(state_names)
        read_outputs, read_flags = slave.real_reader(output_names), slave.bool_reader(flag_names)
        write_inputs = slave.real_writer(["v_cmd", "w_cmd", "push_x", "push_y"])
        slid = sorted({n if ev.trailer is None else ev.trailer for ev in schedule.slides})
        write_slide = {i: slave.real_writer([f"slide[{i}]"]) for i in slid}
        truth, phi_meas = np.zeros(n + 6), np.zeros(n)
        measure = sens.measurer(truth, phi_meas)
        for k in range(n_steps + 1):
            t = t0 + k * step
            # apply inputs
            for bias in schedule.biases_due(t):
                sens.set_bias(bias.joint, bias.bias)
            truth[:] = read_state()
            v_cmd, w_cmd, _, ref = loop.command(t, measure())
            x_n, y_n, th_n = truth[3:6].tolist()
            push_x, push_y = schedule.push_force(t, th_n) if schedule.pushes else (0.0, 0.0)
            if reference is None:  # open loop: no errors, the one NaN (math.nan's bits)
                errors = (math.nan, math.nan, math.nan)
            else:
                dx, dy = x_n - ref.x, y_n - ref.y
                c, s = math.cos(ref.theta), math.sin(ref.theta)
                errors = (c * dx + s * dy, -s * dx + c * dy, wrap_scalar(th_n - ref.theta))
            write_inputs((v_cmd, w_cmd, push_x, push_y))
            for i, speed in schedule.slide_changes(t) if schedule.slides else ():
                write_slide[i]((speed,))
            slide = schedule.slide_speed(n) if schedule.slides else 0.0
            # record
            out = read_outputs().tolist()
            flags = [float(f) for f in read_flags()]
            b = n + 1
            row = ([t] + out[:5 * b + n] + phi_meas.tolist() + out[5 * b + n:5 * b + 2 * n]
                   + f_lat_max + flags[:n] + out[5 * b + 2 * n:]
                   + [v_cmd, w_cmd, push_x, push_y, slide] + list(ref) + list(errors)
                   + [flags[n]])
            rows.append(row)
            if flags[n]:
                phi = out[5 * b:5 * b + n]
                worst = int(np.argmax(np.abs(phi))) + 1
                status, message = "jackknifed", (
                    f"jackknife at t = {t:.3f} s: |phi[{worst}]| = "
                    f"{math.degrees(abs(phi[worst - 1])):.1f} deg exceeds phi_max")
                break
            if goal is not None and t >= t_end - 1e-12:
                dist = math.hypot(x_n - goal[0], y_n - goal[1])
                if (dist <= goal_tolerance[0]
                        and abs(wrap_scalar(th_n - goal[2])) <= goal_tolerance[1]):
                    status, message = "goal_reached", (
                        f"goal reached at t = {t:.3f} s ({dist * 100:.1f} cm from the goal)")
                    break
            if k == n_steps:
                break
            slave.do_step(t, step)
    except CosimError as exc:
        status, message = "fmu_error", str(exc)
    except ControllerError as exc:
        status, message = "fmu_error", f"controller failed: {exc}"
    finally:
        slave.close()
    data = np.array([tuple(r) for r in rows], dtype=[(c, "f8") for c in columns(n)])
    return status, message, data
