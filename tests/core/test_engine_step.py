"""The co-simulation step's closed-loop work in one C call (core/csrc/step.c, pt_step) against
the same work done call by call: the sensors, the compiled law's Tracker.command, and the push
force and tracking errors in Python (cosim/step_loop.py PythonLaw, the hook the master's loop
calls for a law written in Python).
Bit for bit, over a push-pull mission with noisy, quantized, biased sensors with play, a measured
last pose and pushes turning with the trailer."""

import ctypes
import math

import numpy as np
import pytest

from pushtrain.core import native
from pushtrain.core.controller import Controller, ControllerConfig
from pushtrain.core.kinematics import ChainGeometry
from pushtrain.core.reference import Reference
from pushtrain.core.segment import PULL, Segment
from pushtrain.core.sensors import Measurement, SensorConfig, Sensors
from pushtrain.core.tracking import TrackingLoop
from pushtrain.cosim.events import EventSchedule, Push
from pushtrain.cosim.step_loop import PythonLaw
from pushtrain.errors import ControllerError

N = 3
REFERENCE = Reference.from_segments((0.0, 0.0, math.pi), [
    Segment("line", 0.4), Segment("arc", 0.5, 0.8), Segment("line", 0.4, 0.0, PULL),
    Segment("arc", 0.4, -0.7, PULL)], speed=0.08, cusp_dwell=1.0)
SENSORS = SensorConfig(N, joint_bias=[0.01, -0.02, 0.005], joint_noise=0.002,
                       joint_quantization=0.001, joint_backlash=0.004, position_noise=0.01,
                       heading_noise=0.003, localize="last_trailer", seed=5)
EVENTS = [Push(1.0, 3.0, lateral=25.0), Push(2.0, 5.0, fx=5.0, fy=-3.0, lateral=-10.0)]


class _OneCall:
    """The engine's step, ``pt_step``, on the tracker's instant and the sensors' model."""

    def __init__(self, tracker, sensors, events, truth, phi_meas):
        self.tracker, self.events, self.truth, self.phi = tracker, events, truth, phi_meas
        self.sensors = sensors
        self.struct = native.PtStep(track=ctypes.pointer(tracker.instant),
                                    sensors=ctypes.pointer(sensors.model))
        tracker.has_last = bool(sensors.config.measure_last_pose)

    def step(self, t):
        active = self.events.active_pushes(t)
        pushes = np.array([(p.fx, p.fy, p.lateral) for p in active] or [(0.0,) * 3])
        self.struct.n_pushes, self.struct.pushes = len(active), native.dptr(pushes)
        noise = self.sensors.draw_noise(1)
        status = native.load().pt_step(ctypes.byref(self.struct), t, native.dptr(self.truth),
                                       native.dptr(noise), native.dptr(self.phi))
        if status:
            m = self.tracker.instant.m
            raise self.tracker.error(status, t, Measurement(m.x0, m.y0, m.theta0,
                                                            self.phi.tolist(), None), None)
        k, s = self.tracker.instant, self.struct
        sample = s.sample  # the step's own copies of the track's command and sample
        fields = [name for name, _ in sample._fields_]
        assert tuple(s.cmd) == tuple(k.cmd)
        assert [getattr(sample, f) for f in fields] == [getattr(k.sample, f) for f in fields]
        return (s.cmd[0], s.cmd[1], s.push[0], s.push[1], sample.x, sample.y, sample.theta,
                sample.v, sample.w, sample.direction, *s.errors)


def _engine(compiled: bool):
    config = ControllerConfig(geometry=ChainGeometry.uniform(N, 0.52), v_max=0.1, w_max=0.1,
                              acc_max=0.2, alpha_max=math.radians(10.0))
    controller = Controller(config)
    controller.reset(0.0, 0.0, -0.05)
    loop = TrackingLoop(controller, REFERENCE, info=False)
    assert loop.tracker is not None
    truth = np.zeros(N + 6)
    sensors, events = Sensors(SENSORS), EventSchedule(EVENTS, N, 100.0)
    if compiled:
        phi_meas = np.zeros(N)
        return _OneCall(loop.tracker, sensors, events, truth, phi_meas), truth, phi_meas
    law = PythonLaw(truth, sensors, events, loop.command)
    return law, truth, law.phi


def test_one_call_equals_the_work_done_call_by_call():
    (one, truth_a, phi_a), (parts, truth_b, phi_b) = _engine(True), _engine(False)
    rng = np.random.default_rng(3)
    pulled = pushed = 0
    for k in range(400):
        t = 0.05 * k
        # a train near the reference, wandering
        state = np.concatenate(([0.6 - 0.002 * k, 0.01 * math.sin(0.05 * k), math.pi + 0.1,
                                 -0.01 * k, 0.02, math.pi - 0.05], rng.normal(0.0, 0.1, N)))
        truth_a[:], truth_b[:] = state, state
        got, want = one.step(t), parts.step(t)
        assert np.array(got).tobytes() == np.array(want).tobytes(), k  # command, push force,
        assert phi_a.tobytes() == phi_b.tobytes(), k  # reference sample and tracking errors
        pulled += got[9] == PULL
        pushed += got[2] != 0.0 and got[3] != 0.0
    assert pulled and pushed > 50


def test_a_refused_step_raises_the_trackers_error():
    engine, truth, _ = _engine(True)
    truth[6] = math.nan
    with pytest.raises(ControllerError, match="non-finite measurement"):
        engine.step(0.0)


def test_a_step_takes_the_law_or_a_profile_and_no_governor_with_a_profile():
    """pt_step refuses neither or both of a law and a profile, and a governor on a profile;
    with a profile alone it commands the profile's value, a rest sample and NaN errors."""
    from pushtrain.core.governor import GovernorConfig, SlipGovernor
    from pushtrain.core.openloop import ConstantCommand

    engine, truth, phi = _engine(True)
    lib, step = native.load(), engine.struct
    profile = ConstantCommand(N, -0.05, 0.02).profile
    governor = SlipGovernor(GovernorConfig(ChainGeometry.uniform(N, 0.52), np.full(N, 40.0),
                                           np.full(N, 3.0), np.full(N, 0.1)))

    def call():
        return lib.pt_step(ctypes.byref(step), 0.0, native.dptr(truth),
                           native.dptr(np.zeros(16)), native.dptr(phi))

    step.profile = ctypes.pointer(profile.struct)
    assert call() == 5  # PT_ERR_ARGUMENT: both
    step.track = None
    assert call() == 0
    assert tuple(step.cmd) == (-0.05, 0.02) and step.sample.direction == 0
    assert all(math.isnan(e) for e in step.errors) and math.isnan(step.sample.x)
    step.governor, step.governor_work = ctypes.pointer(governor.struct), native.dptr(governor.work)
    assert call() == 5  # a governor on a profile
    step.governor, step.profile = None, None
    assert call() == 5  # neither
