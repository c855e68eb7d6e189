"""The product's own defaults that the paper does not give (Table 1's are in
:mod:`pushtrain.table1`), written once for every room: the scenario file, the planner's and the
co-simulation's library defaults all read them. SI units, radians."""

from __future__ import annotations

import math

__all__ = ["CUSP_DWELL", "GOAL_HEADING_TOLERANCE_DEG", "GOAL_TOLERANCE", "REFERENCE_SPEED",
           "ROBOT_LENGTH", "ROBOT_WIDTH", "SETTLE_TIME"]

REFERENCE_SPEED = 0.08
"""Speed of a planned path's reference [m/s]: below the robot's 0.1 m/s, so that along-track
lag can be made up."""

CUSP_DWELL = 1.0
"""Rest of the reference at each change of direction [s]."""

SETTLE_TIME = 20.0
"""Time a run goes on after the reference's end for the train to settle [s]."""

GOAL_HEADING_TOLERANCE_DEG = 5.0
"""Heading tolerance of the goal test [deg] (as the scenario file gives it)."""

GOAL_TOLERANCE = (0.05, math.radians(GOAL_HEADING_TOLERANCE_DEG))
"""The goal test: the last trailer within 0.05 m and 5 deg of the goal [m, rad]."""

ROBOT_LENGTH = 0.6
"""The robot's footprint along its heading [m]."""

ROBOT_WIDTH = 0.5
"""The robot's footprint across its heading [m]."""
