"""Shortcuts of a planned path (:mod:`pushtrain.planner.smooth`): a shortcut is taken only when
it is cheaper, so the smoothed path never costs more than the raw one, and a detour through
free space is cut short."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from pushtrain.core.segment import PUSH, Segment
from pushtrain.planner.smooth import junction_poses, path_cost, shortcut

R = 1.0  # turning radius [m]


def _detour():
    """Out and back around nothing: left, up 2 m, right, right, down 2 m, left: it ends 4 m
    ahead of its start, heading as it started (10.3 m long where 4 m would do)."""
    quarter = R * math.pi / 2
    return [Segment("arc", quarter, 1 / R, PUSH), Segment("line", 2.0, 0.0, PUSH),
            Segment("arc", quarter, -1 / R, PUSH), Segment("arc", quarter, -1 / R, PUSH),
            Segment("line", 2.0, 0.0, PUSH), Segment("arc", quarter, 1 / R, PUSH)]


def _free(segments):
    """The check of a path in an empty hall: every path is free (the geometry is what we test)."""
    return SimpleNamespace(ok=True, segments=segments)


def test_a_detour_in_free_space_is_cut_and_never_costs_more():
    start = (0.0, 0.0, 0.0)
    raw = _detour()
    goal = junction_poses(start, raw)[-1]
    smoothed, check, taken = shortcut(raw, _free(raw), start, goal, R, _free)
    assert taken >= 1 and check.ok
    assert path_cost(smoothed) <= path_cost(raw)
    assert sum(s.length for s in smoothed) < 0.6 * sum(s.length for s in raw)
    end = junction_poses(start, smoothed)[-1]  # the same goal, reached
    np.testing.assert_allclose(end[:2], goal[:2], atol=1e-6)
    assert math.cos(end[2] - goal[2]) == pytest.approx(1.0, abs=1e-9)


def test_a_shortcut_that_fails_its_check_is_not_taken():
    start = (0.0, 0.0, 0.0)
    raw = _detour()
    goal = junction_poses(start, raw)[-1]

    def blocked(segments):  # a wall across the straight way: only the raw path is free
        return SimpleNamespace(ok=segments == raw)

    smoothed, _, taken = shortcut(raw, _free(raw), start, goal, R, blocked)
    assert taken == 0 and smoothed == raw


def test_a_straight_path_stays_as_it_is():
    start = (0.0, 0.0, 0.0)
    raw = [Segment("line", 4.0, 0.0, PUSH)]
    goal = junction_poses(start, raw)[-1]
    smoothed, _, taken = shortcut(raw, _free(raw), start, goal, R, _free)
    assert taken == 0 and path_cost(smoothed) <= path_cost(raw)
