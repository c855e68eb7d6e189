"""Tests of the closed loop's per-step logic (pushtrain.core.tracking)."""

import math

import numpy as np
from reference.controller import BackwardController

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.openloop import ConstantCommand
from pushtrain.core.pulling import PullGuide
from pushtrain.core.reference import Reference
from pushtrain.core.segment import PULL, PUSH, REST, Segment
from pushtrain.core.sensors import Measurement
from pushtrain.core.tracking import TrackingLoop


def _reference():
    return Reference.from_segments(
        (0.0, 0.0, math.pi),
        [Segment("line", 0.4), Segment("arc", 0.5, 1.0), Segment("arc", 0.4, -0.8, PULL)],
        speed=0.08, cusp_dwell=1.0)


def test_a_step_is_the_reference_sample_the_guide_and_the_controller():
    """Against the same calls made by hand at push, dwell, pull and after the goal."""
    reference = _reference()
    config = ControllerConfig.uniform(3)
    loop = TrackingLoop(BackwardController(config), reference)
    by_hand = BackwardController(config)
    guide = PullGuide(reference, config.geometry)
    meas = Measurement(0.5, 0.1, math.pi + 0.1, np.array([0.05, -0.02, 0.1]))
    t_pull = reference.pull_intervals()[0][0]
    seen = set()
    for t in (0.0, 3.0, 11.5, t_pull + 0.5, t_pull + 3.0, reference.t_end + 1.0):
        v, w, info, ref = loop.command(t, meas)
        expected_ref = reference.sample_at(t)
        leader = guide.sample_at(t) if expected_ref.direction == PULL else None
        v_hand, w_hand, info_hand = by_hand.command(t, meas, expected_ref, leader)
        assert ref == expected_ref
        assert (v, w, info) == (v_hand, w_hand, info_hand)
        seen.add(ref.direction)
    assert seen == {PUSH, REST, PULL}


def test_no_guide_without_pulling_or_without_a_chain_model():
    push_only = Reference.from_segments((0.0, 0.0, math.pi), [Segment("line", 1.0)], speed=0.08)
    assert TrackingLoop(BackwardController(ControllerConfig.uniform(2)), push_only).guide is None
    assert TrackingLoop(ConstantCommand(2, -0.05), _reference()).guide is None
    assert TrackingLoop(BackwardController(ControllerConfig.uniform(2)), _reference()).guide


def test_open_loop_without_a_reference_gets_a_resting_nan_sample():
    loop = TrackingLoop(ConstantCommand(2, -0.05, 0.01), None)
    v, w, info, ref = loop.command(3.0, Measurement(0.0, 0.0, 0.0, np.zeros(2)))
    assert (v, w, info) == (-0.05, 0.01, None)
    assert ref.direction == REST and (ref.v, ref.w) == (0.0, 0.0)
    assert all(math.isnan(a) for a in ref[:3])


def test_command_from_follows_the_reference_it_is_given():
    """BackwardController.command_from equals a TrackingLoop of the reference of each call, also
    when the calls switch to another reference (its own pull guide)."""
    config = ControllerConfig.uniform(3)
    ctrl = BackwardController(config)
    meas = Measurement(0.5, 0.1, math.pi + 0.1, np.array([0.05, -0.02, 0.1]))
    other = Reference.from_segments(
        (0.0, 0.0, math.pi),
        [Segment("line", 0.4), Segment("arc", 0.5, 1.0), Segment("arc", 0.4, 0.9, PULL)],
        speed=0.08, cusp_dwell=1.0)
    t = other.pull_intervals()[0][0] + 2.0
    for reference in (_reference(), other, _reference()):
        ctrl.reset()
        expected = TrackingLoop(BackwardController(config), reference).command(t, meas)
        assert expected[3].direction == PULL
        assert ctrl.command_from(reference, t, meas) == expected[:3]
