"""The product's own defaults that the paper does not give (Table 1's are in
:mod:`pushtrain.table1`), written once for every room: the scenario file, the planner's and the
co-simulation's library defaults all read them. SI units, radians."""

from __future__ import annotations

import math

__all__ = ["ACC_MAX", "ALPHA_MAX_DEG", "CUSP_DWELL", "GOAL_HEADING_TOLERANCE_DEG",
           "GOAL_TOLERANCE", "K_THETA", "K_X", "K_Y", "REFERENCE_SPEED", "REST_SPEED",
           "ROBOT_LENGTH", "ROBOT_WIDTH", "SETTLE_TIME", "V_MAX", "W_MAX"]

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

K_X = 1.0
"""Kanayama's along-track gain K_x [1/s] (Eq. 3)."""

K_Y = 4.0
"""Kanayama's lateral gain K_y [1/m^2] (Eq. 4): lateral errors decay over about 0.5 m."""

K_THETA = 4.0
"""Kanayama's heading gain K_theta [1/m] (Eq. 4)."""

V_MAX = 0.1
"""The robot's speed limit [m/s] (the paper's robot)."""

W_MAX = 0.1
"""The robot's yaw-rate limit [rad/s] (the paper's robot; a scenario gives it as
``w_max_deg``, whose radians differ from this in the last bit)."""

ACC_MAX = 0.2
"""Rate limit of the speed command [m/s^2]."""

ALPHA_MAX_DEG = 10.0
"""Rate limit of the yaw-rate command [deg/s^2]: the paper keeps |alpha| <= 10 deg/s^2 to avoid
lateral wheel slip (Sec. 4.4)."""

REST_SPEED = 1e-9
"""|v_d| [m/s] at or below which the reference counts as resting (the command is zero)."""

ROBOT_LENGTH = 0.6
"""The robot's footprint along its heading [m]."""

ROBOT_WIDTH = 0.5
"""The robot's footprint across its heading [m]."""

PULL_GUIDE_STEP = 0.02
"""RK4 step of the pull guide's backward runs [s]: 1.6 mm of travel at 0.08 m/s."""

ROLLOUT_STEP = 0.025
"""Control and RK4 step of the engine's closed loop in a planner's rollout or check [s] (the
zero-order hold's error is first order in it: 0.36 cm on a bay plan with 0.24 m transients, see
:class:`pushtrain.planner.config.TrackerConfig`)."""

ROLLOUT_SETTLE_TIME = 2.0
"""Time the engine's closed loop runs on after the reference's end in a planner's rollout or
check [s] (the co-simulation's is :data:`SETTLE_TIME`)."""

GRAVITY = 9.81
"""Gravitational acceleration [m/s^2] (the FMU's ``g`` and the governor's)."""

ROBOT_TAU = 0.05
"""Time constant of the robot's velocity loop (first-order lag) [s]: the FMU's ``robot_tau`` and
the slip governor's model of it."""

ROBOT_ACC_MAX = 1.0
"""The robot's velocity loop's acceleration limit [m/s^2] (the FMU's ``robot_acc_max``)."""

ROBOT_ALPHA_MAX = 2.0
"""The robot's velocity loop's yaw-acceleration limit [rad/s^2] (``robot_alpha_max``)."""

GOVERNOR_FRACTION = 0.8
"""Share of the friction limit the slip governor lets the predicted lateral forces use [-]."""

__all__ += ["GOVERNOR_FRACTION", "GRAVITY", "PULL_GUIDE_STEP", "ROBOT_ACC_MAX", "ROBOT_ALPHA_MAX",
            "ROBOT_TAU", "ROLLOUT_SETTLE_TIME", "ROLLOUT_STEP"]
