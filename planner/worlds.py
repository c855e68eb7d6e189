"""Reusable test and example worlds (plain data, as in a scenario file).

Each factory returns a dict ``{"world": {...}, "start": [x, y, theta], "goal": [x, y, theta],
"description": str}``; ``world`` is accepted by :meth:`pushtrain.planner.World.from_dict` and
``start``/``goal`` are last-trailer poses in the chain convention (theta toward the robot, so a
train pushed toward +x has theta = pi). Example scenario TOML files describe the same corridors.
"""

from __future__ import annotations

import math

__all__ = ["straight_corridor", "l_corridor", "bay", "two_rooms", "CASES"]


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


CASES = {
    "straight": straight_corridor,
    "l_2.0": lambda: l_corridor(2.0),
    "l_1.5": lambda: l_corridor(1.5),
    "bay": bay,
}
"""Named planning cases used by the tests and the benchmark."""
