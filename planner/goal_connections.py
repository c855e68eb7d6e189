"""The lattice search's ways to the goal: the connections a node tries to reach it in one go.

From a node's reference pose, in the order tried (the driver's first):

- **corner**: straight, one arc, straight (:func:`~pushtrain.planner.connect.corner_segments`),
  pushing, or pulling where the chain is straight enough to pull, with the radii of
  ``corner_radii``;
- **straighten**: where the chain is too bent to pull, a straight push of ``straighten``
  metres first, then the pulled corner;
- **pullback**: where the route comes in across the goal (up a corridor into a T junction whose
  goal faces along the hall), a corner push into the junction's far branch whose last straight
  is as long as the train, then a pull back onto the goal (:meth:`GoalConnections.pullbacks`);
- **approach** and **direct**: Reeds-Shepp paths (radius ``turning radius * f`` for f in
  ``analytic_radii``) to a pose ``approach`` metres before the goal followed by a straight push
  onto it (the followers line up behind the last trailer before it arrives), and straight to
  the goal.

Each candidate is a list of segments; the search checks it cheaply and then tracks it in closed
loop (:class:`~pushtrain.planner.lattice.Search`). Units: SI, radians.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Iterator

import numpy as np

from pushtrain.core.segment import PULL, PUSH, Segment

from .connect import corner_segments, sample_reference
from .propagate import Propagator
from .reeds_shepp import rs_segments
from .route import Route, comes_in_across, starts_against
from .train import Train

__all__ = ["GoalConnections"]

log = logging.getLogger(__name__)


class GoalConnections:
    """The connections to ``goal`` of one search.

    Parameters
    ----------
    train : Train
    propagator : Propagator
        Its distance field and its checks of a train state (the pull-backs' starts).
    goal : (x, y, theta)
        The last trailer's goal pose [m, m, rad].
    settings : LatticeSettings
        The search's settings (radii, pull rule, pull-back parameters).
    reach : float
        The longest straight a connection may have [m] (the map's diagonal).
    route : callable
        Returns the route through the building, or None (asked only for the pull-backs).
    clear : callable
        ``clear(pose, segments)``: whether the last trailer's footprint keeps its clearance
        along ``segments`` from ``pose`` (the search's cheap reference test).
    start : (x, y, theta) or None
        The last trailer's start pose (the K-turns are tried only where the train must turn
        round: the route leaves against it and goes round no loop).
    """

    def __init__(self, train: Train, propagator: Propagator, goal, settings, reach: float,
                 route: Callable[[], Route | None], clear: Callable[..., bool], start=None):
        self.train = train
        self.start = start
        self._turning: bool | None = None
        self.prop = propagator
        self.goal = goal
        self.s = settings
        self.reach = reach
        self._route = route
        self._clear = clear
        self._pullback_starts: list | None = None

    def candidates(self, pose, phi, kturns: bool = True) -> Iterator[tuple[tuple, list[Segment]]]:
        """(kind, segments) of every connection from reference ``pose`` (x, y, theta) with the
        chain's joint angles ``phi`` (n,) [rad], in the order of the module docstring (without
        the K-turns unless ``kturns``: their checks of the straight train cost a millisecond
        each, and the search tries them only every few expansions)."""
        s = self.s
        bend = float(np.abs(phi).max())
        bent = bend > s.pull_phi
        for direction in (PUSH, PULL):
            if direction == PULL and bent:
                continue
            for factor in s.corner_radii:
                path = corner_segments(pose, self.goal, direction, s.radius * factor,
                                       max_reach=self.reach)
                if path:
                    yield ("corner", direction, factor), path
        if bent:
            for d in s.straighten:
                push = Segment("line", d, 0.0, PUSH)
                ahead = sample_reference(pose, [push], d)[-1]
                for factor in s.corner_radii:
                    path = corner_segments(ahead, self.goal, PULL, s.radius * factor,
                                           max_reach=self.reach)
                    if path:
                        yield ("straighten", d, factor), [push] + path
        for start, pull in self.pullbacks():
            for factor in s.corner_radii:  # the tightest corner whose reference is clear
                push = corner_segments(pose, start, PUSH, s.radius * factor,
                                       max_reach=self.reach)
                if push and self._straightens(push, bend) and self._clear(pose, push):
                    yield ("pullback", factor), push + pull
                    break
        if kturns:
            yield from self.kturns(pose, bent)
        gx, gy, gth = self.goal
        pre = (gx + s.approach * math.cos(gth), gy + s.approach * math.sin(gth), gth)
        for factor in s.analytic_radii:
            radius = s.radius * factor
            if s.approach > 0.0:
                head = rs_segments(pose, pre, radius)
                if head:
                    yield ("approach", factor), head + [Segment("line", s.approach, 0.0, PUSH)]
            direct = rs_segments(pose, self.goal, radius)
            if direct is not None:
                yield ("direct", factor), direct

    def kturns(self, pose, bent: bool) -> Iterator[tuple[tuple, list[Segment]]]:
        """A K-turn's last legs from ``pose``: a straight push as long as the train plus
        ``kturn_push`` (the train straightens in the branch; none where the chain is already
        straight enough to pull), a straight pull back along that line until the goal's line
        is ``kturn_extra`` [m] beyond the corner's tangent, then the driver's corner push onto
        the goal (arc of the turning radius). What a tugger driver does in a T junction to go
        back down the corridor he came up. Only where the straight train fits at the pull's
        both ends."""
        if not self.turning_round():
            return
        s = self.s
        gx, gy, gth = self.goal
        bx, by = math.cos(gth), math.sin(gth)
        pushes = [self.train.hitch_length + e for e in s.kturn_push]
        for push_length in ([] if bent else [0.0]) + pushes:
            head = [Segment("line", push_length, 0.0, PUSH)] if push_length > 0.0 else []
            ahead = tuple(map(float, sample_reference(pose, head, 0.05)[-1])) if head else pose
            ux, uy = math.cos(ahead[2]), math.sin(ahead[2])  # a pull moves along theta
            cross = ux * by - uy * bx
            if abs(cross) < math.sin(s.kturn_min_turn):
                return  # the lines are (nearly) parallel: no corner between them
            meet = ((gx - ahead[0]) * by - (gy - ahead[1]) * bx) / cross
            turn = math.pi - math.acos(max(-1.0, min(1.0, ux * bx + uy * by)))
            if not self._straight_fits(ahead):
                continue
            for extra in s.kturn_extra:
                pull = meet + s.radius * math.tan(0.5 * turn) + extra
                if not 0.3 <= pull <= self.reach:
                    continue
                back = (ahead[0] + pull * ux, ahead[1] + pull * uy, ahead[2])
                corner = corner_segments(back, self.goal, PUSH, s.radius, max_reach=self.reach)
                if corner and self._straight_fits(back):
                    yield (("kturn", push_length, extra),
                           head + [Segment("line", pull, 0.0, PULL)] + corner)

    def turning_round(self) -> bool:
        """Whether the train must turn round without a loop to go round: the route leaves
        against the start's direction of travel and is no loop (decided once)."""
        if self._turning is None:
            route = self._route() if self.start is not None else None
            self._turning = (route is not None and not route.loop
                             and starts_against(route, self.start))
        return self._turning

    def _straight_fits(self, pose) -> bool:
        """Whether the straight train with its last trailer at ``pose`` is clear."""
        state = self.prop.initial_state(pose, np.full(self.train.n + 1, pose[2]))
        failure, _ = self.prop.check(np.array([state.z]))
        return failure is None

    def pullbacks(self) -> list:
        """The pull-back connections' pulls onto the goal: (the pose the pull starts from, its
        segments), made once; none unless the route comes in across the goal.

        A tugger driver whose train comes up a corridor into a T junction, and must leave it
        at the junction pushed along the hall, cannot push round onto it: the train behind
        the last trailer would have to lie in the hall the other way. He pushes round the
        corner into the hall's other branch until the train is straight there, then pulls it
        back onto the junction, straight and turning at the end. Each pull here is such a
        pull, computed backward from the goal: a straight pull as long as the train plus
        ``pullback_extra`` (the whole train lies straight on it, as the pull rule asks),
        then an arc of the turning radius turning ``pullback_turns`` and a straight pull of
        each of ``pullback_settle`` onto the goal. Of these, for each settling length, the
        ``pullback_keep`` whose reference
        keeps farthest from the walls (the middle of the branch, where a driver straightens
        his train) among those where the last trailer's footprint clears the pull and the
        straight train fits at its start.
        """
        if self._pullback_starts is not None:
            return self._pullback_starts
        self._pullback_starts = []
        route = self._route()
        if route is None or not comes_in_across(route, self.goal, self.s.pullback_enter):
            return self._pullback_starts
        s = self.s
        for group, settle in enumerate(s.pullback_settle):
            candidates = []
            for extra in s.pullback_extra:
                for turn in s.pullback_turns:
                    if turn == 0.0 and group > 0:
                        continue  # a straight pull has no settling straight: tried once
                    pull = [Segment("line", self.train.hitch_length + extra, 0.0, PULL)]
                    if turn != 0.0:
                        pull.append(Segment("arc", abs(turn) * s.radius,
                                            math.copysign(1.0 / s.radius, turn), PULL))
                        pull.append(Segment("line", settle, 0.0, PULL))
                    poses = sample_reference(self.goal, _reversed(pull), 0.05)
                    room = float(self.prop.field.at(poses[:, 0], poses[:, 1]).min())
                    candidates.append((-room, len(candidates), tuple(map(float, poses[-1])),
                                       pull))
            # the roomiest first, checked until enough pass (the checks cost a millisecond
            # each); as many for each settling length
            kept = 0
            for _, _, start, pull in sorted(candidates):
                if kept >= s.pullback_keep:
                    break
                if not self._clear(start, pull):
                    continue
                state = self.prop.initial_state(start, np.full(self.train.n + 1, start[2]))
                failure, _ = self.prop.check(np.array([state.z]))
                if failure is None:
                    self._pullback_starts.append((start, pull))
                    kept += 1
        log.debug("pull-back connections from %s", [p for p, _ in self._pullback_starts])
        return self._pullback_starts

    def _straightens(self, push: list[Segment], bend: float) -> bool:
        """Whether the push before a pull-back ends on a straight as long as the train (the
        chain straightens on it, so the pull may start), or is one straight push of a train
        whose largest |phi_i| ``bend`` [rad] is within the pull rule already."""
        last = push[-1]
        if last.kind != "line":
            return False
        if last.length >= self.train.hitch_length:
            return True
        return len(push) == 1 and bend <= self.s.pull_phi


def _reversed(segments: list[Segment]) -> list[Segment]:
    """The segments travelled backward: from their end to their start."""
    return [Segment(g.kind, g.length, -g.curvature, -g.direction) for g in reversed(segments)]
