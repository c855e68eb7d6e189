"""Settings of the lattice search (:class:`~pushtrain.planner.lattice.Search`) and the cost it
prices motions by (:func:`segments_cost`, also the smoothing's). SI units, radians."""

from __future__ import annotations

import math
from dataclasses import dataclass

from pushtrain.core.segment import PULL, PUSH

from .config import PlannerConfig

__all__ = ["LatticeSettings", "segments_cost"]


@dataclass(frozen=True)
class LatticeSettings:
    """Settings of :class:`Search` (SI units, radians; see the module docstring).

    Attributes
    ----------
    radius : float
        The turning radius [m]: pushing primitives' curvatures are ``k / radius`` for k in
        ``curvatures``, pulling ones for k in ``pull_curvatures`` (a driver pulls straight or
        gently turning); connections use multiples of it.
    step_length, pull_length, long_straight : float
        Length [m] of a pushing primitive, of a pulling one, and of the one long straight push.
    approach : float
        Length [m] of the straight push onto the goal that ends the approach connections.
    grid_xy, grid_theta, grid_bend : float
        Cells of the duplicate pruning: reference position [m], heading [rad], and the chain's
        bend (robot heading minus last trailer heading) [rad].
    weight : float
        Heuristic weight (>= 1).
    turn_weight, pull_turn_weight, change_weight, cusp_cost, pull_factor : float
        The cost (:func:`segments_cost`): per radian turned pushing and pulling, per change of
        curvature, per cusp, and the factor of a pulled metre.
    pull_phi : float
        The pull rule: the largest |phi_i| [rad] a pulling run may start from.
    max_pull_run : float
        Longest pulling run [m] of primitives (each continuation rolls the run out again).
    inch_fractions : tuple of float
        Fractions of the primitives' lengths tried, in turn, from a start none of whose
        full-length motions succeeded (inching out of a tight spot). Only from the start:
        inside the search, a node whose motions all fail is a dead end, and inching from every
        such node doubled the expansions of the three-point turn.
    follow_lengths : tuple of float
        How far ahead along the route [m] the route-following pushes aim (see
        :meth:`Search._follow`).
    follow_offset, follow_angle : float
        Farthest distance [m] of the reference from the route, and largest angle [rad] between
        the direction it pushes and the route's, for a route-following push.
    follow_turn, follow_turn_bent : float
        Largest turn [rad] of the route over the stretch a route-following push covers, from a
        straight chain (every |phi_i| <= ``pull_phi``) and from a bent one: sharper corners and
        junctions are left to the primitives and the connections. Without the limit, pushes
        round the corner of the 1.3 m L with five trailers cost 4 times the expansions; with one
        limit for all, 60 deg gave that L two cusps and 45 deg lost the bookstore's U-turn.
    analytic_radii, corner_radii : tuple of float
        Radii (in turning radii) of the Reeds-Shepp connections and of the corner connections,
        in the order tried (the tightest corner first: the shortest path).
    straighten : tuple of float
        Lengths [m] of the straight pushes tried before a pulled corner connection when the
        chain is too bent to pull.
    pullback_enter : float
        Angle [rad] between the route's direction of travel into the goal (over its last
        metre) and the direction the train is pushed at the goal beyond which the search also
        tries the pull-back connections (see :meth:`GoalConnections.pullbacks
    <pushtrain.planner.goal_connections.GoalConnections.pullbacks>`): the route comes in
        across the goal, as up a corridor into a T junction whose goal faces along the hall.
    pullback_turns, pullback_extra : tuple of float
        The pull-back's last pull: the heading it turns [rad] on an arc of the turning radius
        after a straight pull as long as the train plus each of ``pullback_extra`` [m].
    pullback_keep : int
        How many of those pulls are kept: the ones farthest from the walls.
    pullback_settle : tuple of float
        Lengths [m] of the straight pull after the pull-back's arc: the last trailer, which
        cuts the arc's inside while pulled, settles onto the goal's line on it. The shorter
        one is for a goal near the branch's end: the office's T junction with 5 trailers,
        whose 1 m settling pull starts where the push into the branch before it meets the
        wall, plans with 0.5 m (0.5-0.8 m all do).
    kturn_push, kturn_extra : tuple of float
        The K-turn connection (:meth:`GoalConnections.kturns
        <pushtrain.planner.goal_connections.GoalConnections.kturns>`): where the chain is bent,
        a straight push as long as the train plus each of ``kturn_push`` [m] first; the
        pull back goes ``kturn_extra`` [m] beyond the corner's tangent point.
    kturn_min_turn : float
        The least turn [rad] from the pull's line onto the goal's for a K-turn corner.
    analytic_every, analytic_per_node : int
        Reeds-Shepp connections are tried every ``analytic_every`` expansions; at most
        ``analytic_per_node`` closed-loop connection attempts per node otherwise.
    car_after : int
        Expansions without a path after which the car heuristic is built.
    budget_steps : int
        Simulated control steps the search may spend (all rollouts together).
    deadline : float
        ``time.perf_counter()`` value at which the search stops.
    """

    radius: float
    curvatures: tuple = (0.0, 1.0, -1.0, 0.5, -0.5)
    pull_curvatures: tuple = (0.0, 0.5, -0.5)
    step_length: float = PlannerConfig.step_length
    pull_length: float = 1.0
    long_straight: float = 1.5
    approach: float = 1.5
    grid_xy: float = 0.15
    grid_theta: float = math.radians(7.5)
    grid_bend: float = 0.3
    weight: float = PlannerConfig.search_weight
    turn_weight: float = 0.3
    pull_turn_weight: float = 1.0
    change_weight: float = 0.25
    cusp_cost: float = 2.0
    pull_factor: float = 1.2
    pull_phi: float = PlannerConfig.pull_max_phi
    max_pull_run: float = 8.0
    analytic_radii: tuple = (1.6, 1.0)
    corner_radii: tuple = (1.0, 1.6, 3.0)
    straighten: tuple = (1.5, 3.0)
    inch_fractions: tuple = (0.4, 0.15)
    follow_lengths: tuple = (2.0, 4.0, 8.0)
    follow_offset: float = 1.0
    follow_angle: float = math.radians(45.0)
    follow_turn: float = math.radians(60.0)
    follow_turn_bent: float = math.radians(30.0)
    pullback_enter: float = math.radians(60.0)
    pullback_turns: tuple = tuple(math.radians(a) for a in range(-90, 91, 5))
    pullback_extra: tuple = (0.5, 2.0)
    kturn_push: tuple = (0.5,)
    kturn_extra: tuple = (0.3,)
    kturn_min_turn: float = math.radians(30.0)
    pullback_keep: int = 3
    pullback_settle: tuple = (1.0, 0.5)
    analytic_every: int = 4
    analytic_per_node: int = 2
    car_after: int = 20
    budget_steps: int = 10**9
    deadline: float = math.inf


def segments_cost(segments, settings: LatticeSettings, direction: int = 0,
                  curvature: float | None = None) -> float:
    """The search's cost of ``segments`` after a motion in ``direction`` (0: none) with
    ``curvature`` (None: none): length (pulls times ``pull_factor``), the heading turned (times
    ``turn_weight`` pushing, ``pull_turn_weight`` pulling: a turning pull starts from a chain
    its guide did not expect, so the last trailer swings off its path), ``change_weight`` per
    change of curvature and ``cusp_cost`` per direction change."""
    s = settings
    cost = 0.0
    for seg in segments:
        pull = seg.direction == PULL
        turned = abs(seg.curvature) * seg.length
        cost += seg.length * (s.pull_factor if pull else 1.0)
        cost += (s.pull_turn_weight if pull else s.turn_weight) * turned
        if direction in (PUSH, PULL) and seg.direction != direction:
            cost += s.cusp_cost
        if curvature is not None and seg.curvature != curvature:
            cost += s.change_weight
        direction, curvature = seg.direction, seg.curvature
    return cost
