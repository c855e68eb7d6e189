"""The co-simulation step's closed-loop work in one C call (core/csrc/step.c, pt_step) against
the same work done call by call: the sensors, the compiled law's Tracker.command, and the push
force and tracking errors in Python (cosim/step_loop.py EngineStep, the path of a Python law).
Bit for bit, over a push-pull mission with noisy, quantized, biased sensors with play, a measured
last pose and pushes turning with the trailer."""

import math

import numpy as np
import pytest

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.kinematics import ChainGeometry
from pushtrain.core.native_controller import NativeController, Tracker
from pushtrain.core.reference import PULL, Reference, Segment
from pushtrain.core.tracking import TrackingLoop
from pushtrain.cosim.events import EventSchedule, Push
from pushtrain.cosim.sensors import SensorConfig, Sensors
from pushtrain.cosim.step_loop import EngineStep
from pushtrain.errors import ControllerError

N = 3
REFERENCE = Reference.from_segments((0.0, 0.0, math.pi), [
    Segment("line", 0.4), Segment("arc", 0.5, 0.8), Segment("line", 0.4, 0.0, PULL),
    Segment("arc", 0.4, -0.7, PULL)], speed=0.08, cusp_dwell=1.0)
SENSORS = SensorConfig(N, joint_bias=[0.01, -0.02, 0.005], joint_noise=0.002,
                       joint_quantization=0.001, joint_backlash=0.004, position_noise=0.01,
                       heading_noise=0.003, localize="last_trailer", seed=5)
EVENTS = [Push(1.0, 3.0, lateral=25.0), Push(2.0, 5.0, fx=5.0, fy=-3.0, lateral=-10.0)]


def _engine(compiled: bool):
    config = ControllerConfig(geometry=ChainGeometry.uniform(N, 0.52), v_max=0.1, w_max=0.1,
                              acc_max=0.2, alpha_max=math.radians(10.0))
    controller = NativeController(config)
    controller.reset(0.0, 0.0, -0.05)
    loop = TrackingLoop(controller, REFERENCE, info=False)
    tracker = loop.command.__self__
    assert isinstance(tracker, Tracker)
    truth, phi_meas = np.zeros(N + 6), np.zeros(N)
    engine = EngineStep(truth, phi_meas, Sensors(SENSORS), EventSchedule(EVENTS, N, 100.0),
                        loop.command, tracker if compiled else None)
    return engine, truth, phi_meas


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
        assert got[:3] == want[:3], k  # command and reference sample
        assert got[3] == want[3], k  # push force and tracking errors
        assert phi_a.tobytes() == phi_b.tobytes(), k
        pulled += got[2].direction == PULL
        pushed += got[3][0] != 0.0 and got[3][1] != 0.0
    assert pulled and pushed > 50


def test_a_refused_step_raises_the_trackers_error():
    engine, truth, _ = _engine(True)
    truth[6] = math.nan
    with pytest.raises(ControllerError, match="non-finite measurement"):
        engine.step(0.0)
