"""Example facility layouts for tests and examples (plain data, as in a scenario file).

Each factory returns a dict ``{"world": {...}, "start": [x, y, theta], "goal": [x, y, theta],
"description": str}``; ``world`` is accepted by
:meth:`pushtrain.facility.free_space.World.from_dict` and ``start``/``goal`` are last-trailer
poses in the chain convention (theta toward the robot, so a train pushed toward +x has theta =
pi). Example scenario TOML files describe the same corridors.
"""

from __future__ import annotations

import math

__all__ = ["straight_corridor", "l_corridor", "bay", "two_rooms", "docking_bay", "t_junction",
           "narrow_l", "parallel_slot", "corner_long", "CASES"]


def straight_corridor(length: float = 10.0, width: float = 1.5) -> dict:
    """A straight corridor [0, length] x [0, width]; push 3.5 m along +x on the centre line."""
    w = float(width)
    return {
        "description": f"straight corridor {length} m x {width} m",
        "world": {"free": [[0.0, 0.0], [length, 0.0], [length, w], [0.0, w]]},
        "start": [4.0, 0.5 * w, math.pi],
        "goal": [length - 1.0, 0.5 * w, math.pi],
    }


def l_corridor(width: float = 2.0, leg: float = 9.0) -> dict:
    """An L-shaped corridor of ``width`` [m]: a leg along +x, then a left turn up +y.

    Outline: (0, 0) - (leg, 0) - (leg, leg) - (leg - width, leg) - (leg - width, width) -
    (0, width). The train starts in the horizontal leg pushing toward +x (robot behind at -x)
    and ends 1.5 m below the top of the vertical leg, pushing toward +y.
    """
    w, L = float(width), float(leg)
    return {
        "description": f"L corridor, legs {leg} m, width {width} m",
        "world": {"free": [[0.0, 0.0], [L, 0.0], [L, L], [L - w, L], [L - w, w], [0.0, w]]},
        "start": [4.0, 0.5 * w, math.pi],
        "goal": [L - 0.5 * w, L - 1.5, -0.5 * math.pi],
    }


def bay(corridor_width: float = 3.0, bay_width: float = 1.4, bay_depth: float = 3.0) -> dict:
    """A corridor along x with a dead-end bay on its upper side; one direction change needed.

    The train starts with its last trailer already past the bay (x = 11.5, pushing toward +x,
    robot behind at -x) and must end pushed into the bay, last trailer first: the robot pulls
    the train back along the corridor, then pushes it into the bay with a left turn.
    """
    w, bw, bd = float(corridor_width), float(bay_width), float(bay_depth)
    x0 = 8.0
    return {
        "description": f"corridor {w} m wide with a {bw} m x {bd} m bay",
        "world": {
            "free": [[0.0, 0.0], [14.0, 0.0], [14.0, w], [x0 + bw, w], [x0 + bw, w + bd],
                     [x0, w + bd], [x0, w], [0.0, w]]
        },
        "start": [11.5, 0.5 * w, math.pi],
        "goal": [x0 + 0.5 * bw, w + bd - 0.7, -0.5 * math.pi],
    }


def two_rooms(gap: float = 0.0) -> dict:
    """Two rooms joined by a slit of width ``gap`` [m] (0: only touching); goal in the other."""
    g = float(gap)
    free = [[0.0, 0.0], [5.0, 0.0], [5.0, 2.5 - 0.5 * g], [6.0, 2.5 - 0.5 * g], [6.0, 0.0],
            [11.0, 0.0], [11.0, 5.0], [6.0, 5.0], [6.0, 2.5 + 0.5 * g], [5.0, 2.5 + 0.5 * g],
            [5.0, 5.0], [0.0, 5.0]]
    return {
        "description": f"two rooms joined by a {gap} m slit",
        "world": {"free": free},
        "start": [4.0, 2.5, math.pi],
        "goal": [9.0, 2.5, math.pi],
    }


def docking_bay(aisle: float = 2.5, bay_width: float = 0.9, bay_depth: float = 2.5) -> dict:
    """A dead-end bay ``bay_width`` wide and ``bay_depth`` deep off the upper wall of an aisle
    ``aisle`` metres wide (n = 3): the train comes along the aisle pushing toward +x and is
    pushed, last trailer first, into the bay with a left turn. The goal leaves 0.2 m between
    the last trailer's front and the bay's end wall."""
    a, bw, bd = float(aisle), float(bay_width), float(bay_depth)
    xb = 10.0  # the bay's centre line
    free = [[0.0, 0.0], [14.0, 0.0], [14.0, a], [xb + 0.5 * bw, a], [xb + 0.5 * bw, a + bd],
            [xb - 0.5 * bw, a + bd], [xb - 0.5 * bw, a], [0.0, a]]
    return {
        "description": f"aisle {a} m wide with a dead-end bay {bw} m x {bd} m",
        "world": {"free": free},
        "start": [6.0, 0.5 * a, math.pi],
        "goal": [xb, a + bd - 0.6, -0.5 * math.pi],
    }


def t_junction(corridor: float = 2.0, branch: float = 1.6, branch_length: float = 5.0) -> dict:
    """A T-junction: a corridor along x, ``corridor`` wide, with a side branch ``branch`` wide
    and ``branch_length`` long going up from its middle. The train comes pushing toward +x and
    must end turned around (robot toward +x, last trailer west of it) beyond the junction: a
    three-point turn, pushing into the branch and pulling out the other way."""
    c, b, bl = float(corridor), float(branch), float(branch_length)
    free = [[-9.0, 0.0], [9.0, 0.0], [9.0, c], [0.5 * b, c], [0.5 * b, c + bl],
            [-0.5 * b, c + bl], [-0.5 * b, c], [-9.0, c]]
    return {
        "description": f"T-junction, corridor {c} m, branch {b} m x {bl} m: three-point turn",
        "world": {"free": free},
        "start": [-3.0, 0.5 * c, math.pi],
        "goal": [2.5, 0.5 * c, 0.0],
    }


def narrow_l(width: float = 1.3, leg: float = 13.0) -> dict:
    """An L corridor ``width`` wide (n = 5 in the examples): along +x, then left up +y."""
    w, L = float(width), float(leg)
    return {
        "description": f"narrow L corridor {w} m wide, legs {L} m",
        "world": {"free": [[0.0, 0.0], [L, 0.0], [L, L], [L - w, L], [L - w, w], [0.0, w]]},
        "start": [6.5, 0.5 * w, math.pi],
        "goal": [L - 0.5 * w, L - 2.0, -0.5 * math.pi],
    }


def parallel_slot(aisle: float = 2.4, depth: float = 1.1, slot: float = 8.0) -> dict:
    """Parking along a wall: an aisle ``aisle`` wide along x with a slot ``depth`` deep and
    ``slot`` long in its upper wall between two blocks (parked loads). The train comes along the
    aisle pushing toward +x and ends in the slot; the examples ask for the whole train
    straight there (``goal_max_phi_deg``), so the S into the slot must end a train length before the
    goal."""
    a, d, ls = float(aisle), float(depth), float(slot)
    x0 = 3.0
    free = [[-6.0, 0.0], [18.0, 0.0], [18.0, a], [x0 + ls, a], [x0 + ls, a + d], [x0, a + d],
            [x0, a], [-6.0, a]]
    return {
        "description": f"aisle {a} m with a {ls} m x {d} m slot along its wall",
        "world": {"free": free},
        "start": [x0 - 1.0, 0.5 * a, math.pi],
        "goal": [x0 + ls - 0.7, a + 0.5 * d, math.pi],
    }


def corner_long(width: float = 2.5, leg: float = 16.0, n_trailers: int = 10) -> dict:
    """A corridor ``width`` wide with one left corner, for a long train (``n_trailers``)."""
    w, L = float(width), float(leg)
    length = 1.04 * n_trailers
    return {
        "description": f"corridor {w} m wide with a corner, legs {L} m, {n_trailers} trailers",
        "world": {"free": [[0.0, 0.0], [L, 0.0], [L, L], [L - w, L], [L - w, w], [0.0, w]]},
        "start": [length + 1.5, 0.5 * w, math.pi],
        "goal": [L - 0.5 * w, L - 1.5, -0.5 * math.pi],
    }


CASES = {
    "straight": straight_corridor,
    "l_2.0": lambda: l_corridor(2.0),
    "l_1.5": lambda: l_corridor(1.5),
    "bay": bay,
    "docking": docking_bay,
    "t_junction": t_junction,
    "narrow_l": narrow_l,
    "parallel": parallel_slot,
    "corner_10": corner_long,
}
"""Named planning cases used by the tests and the benchmark."""
