"""The planner's pull rules, the repair of paths that break them, and the local search.

Pulls: while pulling the robot leads on a reference of its own, computed backward in time from
a straight chain at the pull's end (:class:`~pushtrain.core.pulling.PullGuide`). Two rules keep
planned pulls within what that can do: the straight train at every pull's end must be free
(:attr:`~pushtrain.planner.config.PlannerConfig.straight_pull_ends`), and a pull must start near the
chain it needs (:attr:`~pushtrain.planner.config.PlannerConfig.pull_start_tolerance`). The motion
validator (:mod:`~pushtrain.planner.ompl_search`) checks them inside each local curve with the
rules built here; the junctions between curves and whole pulls over several curves are checked
and repaired here on the finished path.

Functions here take OMPL objects (space information ``si``, the Reeds-Shepp ``space``, the
motion ``validator``, states) and call their methods; they do not import ompl.
"""

from __future__ import annotations

import math

import numpy as np
from shapely.geometry import Polygon

from pushtrain.core.pulling import straight_chain_mismatch
from pushtrain.facility.free_space import World

from .budget import Work
from .reeds_shepp import sample_curve_into, travel_between_states, wrap_yaw
from .train import Train

__all__ = ["shorten_by_local_search", "pull_end_rule", "first_pull_start_outside",
           "pull_start_rule", "repair_pull_ends", "PULL_RUN_SPACING"]

PULL_RUN_SPACING = 0.02
"""Spacing [m] of the samples of a finished path's pulling runs whose start
:func:`first_pull_start_outside` checks (a length along the path, not the pull guide's RK4 step
in seconds, :data:`pushtrain.defaults.PULL_GUIDE_STEP`)."""


def pull_end_rule(train: Train, world: World, inflation: float):
    """``(x, y, yaw) -> bool``: the train drawn out straight ahead of the last trailer at this
    planner state (bodies 0..n-1 at their link distances) is free with ``inflation`` [m]."""
    ahead = np.cumsum((train.geometry.front + train.geometry.rear)[::-1])[::-1]
    chain_region = world.eroded(inflation)
    leading_bodies = train.bodies[:-1]

    def pull_end_valid(x, y, yaw):
        theta = yaw + math.pi
        c, s = math.cos(theta), math.sin(theta)
        return all(chain_region.contains(Polygon(body.corner_points(x + d * c, y + d * s, theta)))
                   for body, d in zip(leading_bodies, ahead, strict=True))

    return pull_end_valid


def pull_start_rule(train: Train, tolerance: float, start_yaw, start_headings):
    """``(s1, samples) -> bool``: the pull sampled by ``samples`` (K, 3) (planner states),
    starting at state ``s1``, needs a chain within ``tolerance`` [m] of the one it starts from
    (``start_headings`` at the start state, a straight chain elsewhere)."""
    tolerance = float(tolerance)
    start_xy = (float(start_yaw[0]), float(start_yaw[1]))

    def pull_start_valid(s1, samples):
        pts = np.column_stack((samples[:, :2], samples[:, 2] + math.pi))
        at_start = math.hypot(s1.getX() - start_xy[0], s1.getY() - start_xy[1]) < 1e-9
        target = start_headings if at_start else None
        return straight_chain_mismatch(train.geometry, pts, target) <= tolerance

    return pull_start_valid


def first_pull_start_outside(space, states: list, train: Train, tolerance: float, start_headings,
                             spacing: float = PULL_RUN_SPACING):
    """The first pull of the path (a whole run over any number of local curves) that starts
    farther than ``tolerance`` from the chain it needs, as (x, y, mismatch), or None.

    The motion validator checks the part of a pull inside one local curve; this checks whole
    runs on the finished path, sampled every ``spacing`` metres. The chain a run starts from is
    ``start_headings`` at the start (None: straight) and a straight chain after a cusp."""
    tmp = space.allocState()
    rows = [(states[0].getX(), states[0].getY(), states[0].getYaw())]
    for a, b in zip(states[:-1], states[1:], strict=True):
        pieces = max(1, int(math.ceil(space.distance(a, b) / spacing)))
        sample_curve_into(rows, space, a, b, pieces, tmp)
    pts = np.array(rows)
    if pts.shape[0] < 2:
        return None
    backward, _, step_length = travel_between_states(pts)
    backward &= step_length > 1e-12
    edges = np.diff(np.concatenate(([0], backward.astype(int), [0])))
    for i0, i1 in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True):
        run = pts[i0:i1 + 1]
        chain = np.column_stack((run[:, :2], run[:, 2] + math.pi))
        target = start_headings if i0 == 0 else None
        mismatch = straight_chain_mismatch(train.geometry, chain, target)
        if mismatch > tolerance:
            return float(run[0, 0]), float(run[0, 1]), mismatch
    return None


def _near(space, state, rng, sigma_xy: float, sigma_yaw: float):
    """A new state at a Gaussian distance from ``state`` (sigmas in m and rad)."""
    cand = space.allocState()
    cand.setX(state.getX() + sigma_xy * rng.standard_normal())
    cand.setY(state.getY() + sigma_xy * rng.standard_normal())
    cand.setYaw(wrap_yaw(state.getYaw() + sigma_yaw * rng.standard_normal()))
    return cand


def _fits(si, validator, states: list, i: int, middle: list) -> bool:
    """``states[i - 1] -> middle... -> states[i + 1]`` (in place of ``states[i]``) is free, and
    the pull-end rule holds at every junction it touches."""
    seq = [states[i - 1], *middle, states[i + 1]]
    if not all(si.checkMotion(a, b) for a, b in zip(seq[:-1], seq[1:], strict=True)):
        return False
    seq = states[max(0, i - 2):i - 1] + seq + states[i + 2:i + 3]
    return all(validator.junction_pull_end_ok(a, b, c)
               for a, b, c in zip(seq[:-2], seq[1:-1], seq[2:], strict=True))


def repair_pull_ends(si, space, validator, states: list, seed: int, tries: int = 40):
    """Move every cusp of the path where a pull ends with a blocked straight train.

    The motion validator checks the straight train at pull ends inside a local curve; a pull
    that ends exactly at a state between two curves is only seen here. Each such state is
    dropped if its neighbours connect directly, else replaced by the first of ``tries``
    random states near it (0.25 m, 0.35 rad; numpy generator seeded with ``seed``) whose two
    curves are free and whose own and neighbouring junctions pass. ``states`` is edited in
    place. Returns (number of repairs, (x, y) of a junction that could not be repaired or
    None).
    """
    rng = np.random.default_rng(seed)
    repairs, i = 0, 1
    while i < len(states) - 1:
        b = states[i]
        if validator.junction_pull_end_ok(states[i - 1], b, states[i + 1]):
            i += 1
            continue
        if _fits(si, validator, states, i, []):
            del states[i]
            repairs += 1
            continue
        found = None
        for _ in range(tries):
            cand = _near(space, b, rng, 0.25, 0.35)
            if si.isValid(cand) and _fits(si, validator, states, i, [cand]):
                found = cand
                break
        if found is None:
            return repairs, (b.getX(), b.getY())
        states[i] = found
        repairs += 1
        i += 1
    return repairs, None


def shorten_by_local_search(si, space, validator, states: list, work: Work, limit: int, rng,
                            sigma=(0.3, 0.3)) -> list:
    """Shorten the path through ``states`` by moving one interior state at a time: Gaussian
    proposals (``sigma`` in x and y [m] and yaw [rad], halved after 30 proposals in a row
    without a gain), accepted when the path gets shorter, both adjacent curves are free and the
    pull-end rule holds at the moved state and its neighbours; until the step scale falls below
    1 % or ``work`` reaches ``limit`` motion checks. Returns the new list of states."""
    states = list(states)
    scale, misses = 1.0, 0
    while len(states) > 2 and scale > 0.01 and not work.done(limit):
        i = int(rng.integers(1, len(states) - 1))
        a, b, c = states[i - 1], states[i], states[i + 1]
        old = space.distance(a, b) + space.distance(b, c)
        cand = _near(space, b, rng, scale * sigma[0], scale * sigma[1])
        new = space.distance(a, cand) + space.distance(cand, c)
        if new < old - 1e-6 and si.isValid(cand) and _fits(si, validator, states, i, [cand]):
            states[i] = cand
            misses = 0
        else:
            misses += 1
            if misses >= 30:
                scale, misses = 0.5 * scale, 0
    return states
