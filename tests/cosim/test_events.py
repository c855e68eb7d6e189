"""Tests of the event schedule of a co-simulation run (pushtrain.cosim.events)."""

import math

import pytest

from pushtrain.cosim.events import EventSchedule, Push, SetBias, Slide
from pushtrain.errors import CosimInputError

H = 0.005


def test_a_push_acts_from_its_start_up_to_but_not_at_its_end():
    """Exactly zero at t = t0 + duration and after, the full force from t0 on (grid t = k h)."""
    events = EventSchedule([Push(1.0, 0.5, lateral=30.0)], 3, 10.0)
    theta = 0.7
    force = {k: events.push_force(k * H, theta) for k in range(150, 400)}
    assert force[199] == (0.0, 0.0)  # t = 0.995 s
    for k in (200, 250, 299):  # t0, mid-push, the last step before the end
        assert force[k] == (-math.sin(theta) * 30.0, math.cos(theta) * 30.0)
    assert all(force[k] == (0.0, 0.0) for k in range(300, 400))  # t0 + duration and after
    assert sum(f != (0.0, 0.0) for f in force.values()) == round(0.5 / H)


@pytest.mark.parametrize("theta", [0.0, 0.4, -2.0, 3.1])
def test_the_lateral_force_turns_with_the_trailer(theta):
    """Along the left normal of the heading it is given at each step, plus the world force."""
    events = EventSchedule([Push(0.0, 1.0, lateral=-12.0, fx=2.0, fy=-1.0)], 2, 5.0)
    fx, fy = events.push_force(0.5, theta)
    assert ((fx - 2.0) * math.cos(theta) + (fy + 1.0) * math.sin(theta)
            == pytest.approx(0.0, abs=1e-12))
    assert -(fx - 2.0) * math.sin(theta) + (fy + 1.0) * math.cos(theta) == pytest.approx(-12.0)


def test_overlapping_pushes_add():
    events = EventSchedule([Push(0.0, 2.0, fx=1.0), Push(1.0, 2.0, fx=2.5, fy=-1.0)], 1, 5.0)
    assert events.push_force(0.5, 0.0) == (1.0, 0.0)
    assert events.push_force(1.5, 0.0) == (3.5, -1.0)
    assert events.push_force(2.5, 0.0) == (2.5, -1.0)


def test_bias_switches_come_once_in_time_order():
    events = EventSchedule([SetBias(2.0, 1, 0.1), SetBias(1.0, 2, 0.2), SetBias(2.0, 2, 0.0)], 2,
                           5.0)
    assert events.biases_due(0.5) == []
    assert events.biases_due(1.0) == [SetBias(1.0, 2, 0.2)]
    assert events.biases_due(1.5) == []
    assert events.biases_due(3.0) == [SetBias(2.0, 1, 0.1), SetBias(2.0, 2, 0.0)]
    assert events.biases_due(4.0) == []


def test_slide_speeds_are_reported_when_they_change():
    events = EventSchedule([Slide(1.0, 0.5, 0.1), Slide(1.2, 1.0, -0.2, trailer=1)], 3, 5.0)
    assert events.slide_changes(0.5) == []
    assert events.slide_changes(1.0) == [(3, pytest.approx(0.2))]
    assert events.slide_changes(1.1) == []
    assert events.slide_changes(1.2) == [(1, pytest.approx(-0.2))]
    assert events.slide_speed(3) == pytest.approx(0.2) and events.slide_speed(2) == 0.0
    assert events.slide_changes(1.5) == [(3, 0.0)]
    assert events.slide_changes(2.2) == [(1, 0.0)]
    assert events.slide_speed(1) == 0.0


@pytest.mark.parametrize("event, match", [
    (Push(1.0, 0.0), "duration"),
    (Slide(1.0, -1.0, 0.1), "duration"),
    (Slide(1.0, 1.0, 0.1, trailer=4), "trailer"),
    (SetBias(1.0, 0, 0.1), "joint"),
    (Push(-1.0, 1.0), "t = -1.0"),
    (Push(math.nan, 1.0), "t = nan"),
    ("push", "allowed are Push"),
])
def test_bad_events_are_refused(event, match):
    with pytest.raises(CosimInputError, match=match):
        EventSchedule([event], 3, 10.0)


def test_an_event_after_the_run_is_kept_with_a_warning(caplog):
    events = EventSchedule([Push(20.0, 1.0, fx=1.0)], 3, 10.0)
    assert "after the end of the run" in caplog.text
    assert events.push_force(20.5, 0.0) == (1.0, 0.0)
