"""The closed-loop propagator: resumable rollouts equal one run of the whole reference."""

import math

import numpy as np
import pytest
from reference.closed_loop import simulate_tracking

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.reference import Reference
from pushtrain.core.segment import PULL, PUSH, Segment
from pushtrain.facility.free_space import World
from pushtrain.planner.config import TrackerConfig
from pushtrain.planner.footprint import body_samples
from pushtrain.planner.propagate import Cursor, Propagator, last_pose
from pushtrain.planner.train import Train

TRAIN = Train.uniform(3)
OPEN = World.from_dict({"bounds": [-6, -6, 6, 6]})
CONTROLLER = ControllerConfig(geometry=TRAIN.geometry)


def _propagator(tracker=None, world=OPEN, margin=0.0):
    tracker = tracker or TrackerConfig(controller=CONTROLLER)
    return Propagator(TRAIN, CONTROLLER, tracker, world.distance_field(),
                      body_samples(TRAIN, margin), TRAIN.phi_max)


SEGMENTS = [Segment("line", 0.5), Segment("arc", 0.7, 1 / 1.2), Segment("arc", 0.6, -1 / 1.5),
            Segment("arc", 0.8, 1 / 1.5, PULL), Segment("line", 0.6, 0.0, PULL),
            Segment("line", 0.5, 0.0, PUSH)]
START = (0.0, 0.0, math.pi)
HEADINGS = math.pi + np.array([0.4, 0.25, 0.1, 0.0])


def test_pieces_rolled_out_one_after_another_equal_the_whole_run():
    """Pushes continue exactly; a pulling run rolled out from where it began equals its part
    of the whole run of the Python reference loop (tests/reference/closed_loop.py), bit for bit:
    states, reference samples, commands and the controller's memory."""
    whole = simulate_tracking(TRAIN.geometry, Reference.from_segments(START, SEGMENTS, 0.08, 1.0),
                              HEADINGS, CONTROLLER, 0.025, 0.0)
    prop = _propagator()
    state = prop.initial_state(START, HEADINGS)
    assert np.array_equal(np.array(state.z), whole.state[0])
    cursor = Cursor(*START, 0.0, 0)
    for piece in ([SEGMENTS[0]], [SEGMENTS[1]], [SEGMENTS[2]], SEGMENTS[3:5], [SEGMENTS[5]]):
        edge = prop.rollout(state, cursor, piece, pull_phi=math.radians(30.0))
        assert edge.ok, edge.failure
        run = edge.run
        k0, k1 = state.k, edge.state.k
        assert np.array_equal(run.states, whole.state[k0:k1 + 1])
        assert np.array_equal(run.t, whole.t[k0:k1 + 1])
        assert np.array_equal(run.reference, whole.reference[k0:k1])
        assert np.array_equal(run.commands, whole.command[k0:k1])
        assert np.array_equal(run.direction, whole.direction[k0:k1])
        assert (run.end.v_prev, run.end.w_prev) == tuple(whole.command[k1 - 1])
        run = edge
        state, cursor = run.state, run.cursor
    assert state.k == whole.t.size - 1
    assert prop.steps == state.k


def test_a_pull_continued_without_its_beginning_differs():
    """Why the search rolls a growing pull out again from the run's start: the robot's pulling
    reference depends on where the run ends."""
    prop = _propagator()
    state = prop.initial_state(START, np.full(4, math.pi))
    cursor = Cursor(*START, 0.0, 0)
    one = prop.rollout(state, cursor, [Segment("line", 0.6, 0.0, PULL)])
    two = prop.rollout(one.state, one.cursor, [Segment("arc", 0.8, 1.0, PULL)])
    whole = prop.rollout(state, cursor, [Segment("line", 0.6, 0.0, PULL),
                                         Segment("arc", 0.8, 1.0, PULL)])
    assert two.state.k == whole.state.k
    assert np.abs(np.array(two.state.z) - np.array(whole.state.z)).max() > 1e-3


def test_goal_mode_stops_at_the_first_instant_within_the_tolerance():
    tracker = TrackerConfig(controller=CONTROLLER, goal_tolerance=(0.01, math.radians(1.0)))
    prop = _propagator(tracker)
    state = prop.initial_state(START, np.full(4, math.pi))
    segs = [Segment("line", 1.0)]
    goal = Reference.from_segments(START, segs, 0.08, 1.0).goal
    run = prop.rollout(state, Cursor(*START, 0.0, 0), segs, goal=goal)
    assert run.ok and run.goal_error[0] <= 0.01
    x, y, th = prop.last_pose(run.state)
    assert math.hypot(x - goal[0], y - goal[1]) == pytest.approx(run.goal_error[0])
    # one instant earlier it was not yet within the tolerance, or the reference had not ended
    t_end = 1.0 / 0.08
    if (run.state.k - 1) * 0.025 >= t_end - 1e-9:
        before = run.run.states[-2]
        bx, by, _ = last_pose(before, TRAIN.geometry)
        assert math.hypot(bx - goal[0], by - goal[1]) > 0.01
    # a goal the reference does not lead to is missed
    far = (goal[0] + 0.5, goal[1], goal[2])
    missed = prop.rollout(state, Cursor(*START, 0.0, 0), segs, goal=far)
    assert not missed.ok and missed.failure["kind"] == "goal_missed"
    assert missed.failure["distance"] == pytest.approx(0.5, abs=0.03)


def test_the_pull_rule_refuses_a_pull_from_a_bent_chain():
    prop = _propagator()
    bent = prop.initial_state(START, HEADINGS)  # joints 0.15, 0.15, 0.1 rad
    pull = [Segment("line", 0.5, 0.0, PULL)]
    run = prop.rollout(bent, Cursor(*START, 0.0, 0), pull, pull_phi=math.radians(5.0))
    assert not run.ok and run.failure["kind"] == "pull_rule"
    assert run.failure["phi"] == pytest.approx(0.15)
    assert prop.rollout(bent, Cursor(*START, 0.0, 0), pull, pull_phi=0.2).ok
    straight = prop.initial_state(START, np.full(4, math.pi))
    # after a push, the pull starts after the cusp dwell: the rule looks at the chain then
    push = prop.rollout(straight, Cursor(*START, 0.0, 0), [Segment("arc", 1.0, 1.0)])
    late = prop.rollout(push.state, push.cursor, pull, pull_phi=math.radians(5.0))
    assert not late.ok and late.failure["kind"] == "pull_rule"
    assert late.failure["k"] >= push.state.k + int(1.0 / 0.025) - 1


def test_a_wall_stops_the_rollout_with_the_body_and_point():
    world = World.from_dict({"free": [[-6, -0.6], [6, -0.6], [6, 0.6], [-6, 0.6]]})
    prop = _propagator(world=world, margin=0.05)
    state = prop.initial_state((2.0, 0.0, math.pi), np.full(4, math.pi))
    run = prop.rollout(state, Cursor(2.0, 0.0, math.pi, 0.0, 0), [Segment("arc", 1.5, 1.0)])
    assert not run.ok and run.failure["kind"] == "collision"
    assert run.failure["body"] == 3  # the last trailer leads into the upper wall
    assert run.failure["y"] > 0.4
    assert run.state.k < state.k + int(1.5 / 0.08 / 0.025)


def _same_run(a, b) -> bool:
    return (np.array_equal(a.run.t, b.run.t) and np.array_equal(a.run.states, b.run.states)
            and np.array_equal(a.run.commands, b.run.commands)
            and np.array_equal(a.run.reference, b.run.reference)
            and np.array_equal(a.run.direction, b.run.direction)
            and a.failure == b.failure and a.goal_error == b.goal_error
            and a.state.k == b.state.k and np.array_equal(a.state.z, b.state.z)
            and (a.state.v_prev, a.state.w_prev, a.state.t_prev)
            == (b.state.v_prev, b.state.w_prev, b.state.t_prev))


@pytest.mark.parametrize("change, shared", [
    (5, 5),   # the last push after the pulling run: continued after the pull's end
    (2, 2),   # the push before the pulling run
    (4, 3),   # inside the pulling run: its guide changes, so from where the run began
    (1, 1),   # the second segment
    (0, 0),   # the first: nothing shared, simulated from the start
])
def test_a_path_continued_from_another_equals_its_whole_run(change, shared):
    """Smoothing's verification (whole_train._simulate with ``base``) continues a candidate
    from the run of the path it parts from: the result equals the candidate's own whole run
    from the start bit for bit (states, commands, references, failure, goal error, the
    controller's memory), and fewer steps are simulated where they share segments. A
    changed segment inside a pulling run changes that run's guide: the run is continued
    from before the pull began."""
    from pushtrain.planner.whole_train import _shared_until, _simulate

    prop = _propagator()
    goal = None  # (the loop's own tolerance is not what is tested)
    base = _simulate(prop, START, HEADINGS, SEGMENTS, goal, None)
    assert base.ok, base.failure
    g = SEGMENTS[change]
    candidate = list(SEGMENTS)
    candidate[change] = Segment(g.kind, g.length + 0.15, g.curvature, g.direction)
    if change + 1 < len(candidate):  # another way on: a short straight in the same direction
        candidate.insert(change + 1, Segment("arc", 0.2, 0.3, candidate[change].direction))
    whole = _simulate(prop, START, HEADINGS, candidate, goal, None)
    before = prop.steps
    continued = _simulate(prop, START, HEADINGS, candidate, goal, None,
                          base=(SEGMENTS, base))
    assert _same_run(continued, whole)
    k = _shared_until(prop, SEGMENTS, candidate)
    if shared == 0:
        assert k == 0 and prop.steps - before == whole.state.k
    else:
        # the shared time: the first `shared` segments (and the dwell at each cusp)
        t = sum(s.length for s in SEGMENTS[:shared]) / prop.tracker.speed
        kept = SEGMENTS[:shared]
        t += prop.tracker.cusp_dwell * sum(
            a.direction != b.direction for a, b in zip(kept, kept[1:], strict=False))
        assert k == prop.loop.instant_at(t) - 2
        assert prop.steps - before == whole.state.k - k
