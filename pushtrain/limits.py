"""Plausible ranges of the physical parameters a user can set, in one place (SI units, radians).

Each parameter of the TrailerTrain FMU that describes the train or the robot has a :class:`Bound`
with the reason for its range. The FMU's ``min``/``max`` attributes and the C code's checks in
``fmi2ExitInitializationMode`` are generated from this table (``fmu/variables.py``,
``fmu/build.py``), and the scenario model (``mission/scenario.py``) checks the same ranges.
:data:`SCENARIO_BOUNDS` adds the scenario settings that are not FMU parameters (the step,
the horizon, body sizes, speed limits, gains, map coordinates); :data:`MAP_BOUNDS` and
:data:`MAP_YAML_BYTES` bound what a map file may hold.
Per-trailer parameters (``front``, ``mass``, ...) have one bound for every element.

A bound says what is physically plausible for this model, not what the numerics can handle; the
ranges are wide on purpose (tests drive the robot to abrupt stops and frictionless slides).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["BOUNDS", "Bound", "check", "MAP_BOUNDS", "MAP_YAML_BYTES", "SWEEP_MAX_TOTAL"]


@dataclass(frozen=True)
class Bound:
    """The plausible closed range ``[lo, hi]`` of parameter ``name``, in ``unit`` (SI)."""

    name: str
    lo: float
    hi: float
    unit: str  # as in the FMU's modelDescription ("" for dimensionless)
    reason: str

    def contains(self, value: float) -> bool:
        """``lo <= value <= hi`` (False for NaN)."""
        return self.lo <= value <= self.hi

    def message(self, name: str, value) -> str:
        """``"name = value: allowed lo to hi unit (reason)"``; the FMU logs the same text."""
        unit = f" {self.unit}" if self.unit else ""
        shown = f"{value:g}" if isinstance(value, (int, float)) else repr(value)
        return f"{name} = {shown}: allowed {self.lo:g} to {self.hi:g}{unit} ({self.reason})"


_LINK_REASON = "a hitch link shorter than 5 cm or longer than 10 m is not a trailer"

BOUNDS: dict[str, Bound] = {
    bound.name: bound
    for bound in (
        Bound("front", 0.05, 10.0, "m", _LINK_REASON),
        Bound("rear", 0.05, 10.0, "m", _LINK_REASON),
        Bound("mass", 1.0, 10000.0, "kg",
              "a cart under 1 kg or a trailer over 10 t is not what a mobile robot pushes"),
        Bound("inertia", 1e-3, 1e5, "kg.m2",
              "yaw inertia about the axle: from a 1 kg, 10 cm cart to a 10 t, 10 m trailer"),
        Bound("payload", 0.0, 10000.0, "kg", "a load is not negative and not over 10 t"),
        Bound("mu", 0.0, 2.0, "",
              "0 is a frictionless slide; no wheel grips sideways with more than 2 "
              "(rubber on dry concrete is about 1)"),
        Bound("g", 1.0, 30.0, "m/s2", "from the Moon (1.6 m/s2) to beyond Jupiter (24.8 m/s2)"),
        Bound("robot_tau", 1e-3, 10.0, "s",
              "no drive closes its velocity loop faster than 1 ms; a lag over 10 s is not a "
              "velocity loop"),
        Bound("robot_acc_max", 1e-3, 100.0, "m/s2",
              "below 1 mm/s2 the robot hardly starts; above 10 g it is not a mobile robot"),
        Bound("robot_alpha_max", 1e-3, 1e4, "rad/s2",
              "below 1 mrad/s2 the robot hardly turns; 1e4 rad/s2 stops 1 rad/s in 0.1 ms, the "
              "abrupt stop used to study sliding"),
        Bound("phi_max", 0.01, math.pi, "rad",
              "a jackknife limit under 0.6 deg forbids every turn; beyond pi a joint angle "
              "wraps around"),
        Bound("max_substep", 1e-5, 0.1, "s",
              "smaller makes a 0.1 s step take over 1e4 substeps; larger than 0.1 s steps over "
              "the robot's velocity loop"),
        Bound("slip_substep", 1e-6, 0.01, "s",
              "smaller makes a 5 ms step take over 5000 sliding substeps; friction impulses "
              "need substeps well below the 5 ms communication step"),
    )
}
"""The FMU's parameters: each becomes ``min``/``max`` in the modelDescription and a C check."""

SCENARIO_BOUNDS: dict[str, Bound] = {
    bound.name: bound
    for bound in (
        # Scenario settings that are not FMU parameters (named by their scenario path).
        Bound("sim.step", 1e-4, 0.1, "s",
              "the paper samples every 5 ms; a step over 0.1 s lets the chain move further "
              "between two commands than the controller can correct (5 s jackknifes in 9 steps), "
              "one under 0.1 ms only makes the run slow"),
        Bound("sim.horizon", 1e-3, 86400.0, "s",
              "a mission longer than a day of simulated time is not a mission"),
        Bound("body.size", 0.05, 20.0, "m",
              "a body shorter or narrower than 5 cm or longer than 20 m is not a robot or "
              "a trailer"),
        Bound("robot.v_max", 1e-3, 5.0, "m/s",
              "below 1 mm/s the train hardly moves; over 5 m/s is not a robot pushing "
              "trailers indoors"),
        Bound("robot.w_max", 1e-3, 10.0, "rad/s",
              "below 1 mrad/s the robot hardly turns; over 10 rad/s is not a robot "
              "pushing trailers"),
        Bound("rotation.w_max", 1e-3, 10.0, "rad/s",
              "the rotation's peak yaw rate: below 1 mrad/s the robot hardly turns; over "
              "10 rad/s is not a robot pushing trailers"),
        Bound("rotation.alpha", 1e-3, 1e4, "rad/s2",
              "the rotation's yaw acceleration: below 1 mrad/s2 one ramp to the peak lasts "
              "hours; 1e4 rad/s2 reaches 10 rad/s in 1 ms"),
        Bound("rotation.hold", 0.0, 86400.0, "s",
              "a swing that holds its peak yaw rate longer than a day is not a swing"),
        Bound("controller.gain", 1e-3, 1e3, "",
              "Kanayama's gains (1/s, 1/m2, 1/m): gains over 1e3 demand responses far "
              "beyond the robot's 5 ms loop, under 1e-3 do nothing"),
        Bound("map.coordinate", -1e5, 1e5, "m",
              "a facility is smaller than 100 km across"),
        Bound("planner.clearance", 0.0, 1.0, "m",
              "a clearance over 1 m from every wall leaves no corridor a train drives in"),
        Bound("planner.step_length", 0.05, 5.0, "m",
              "search motions shorter than 5 cm cost thousands of rollouts per metre; longer "
              "than 5 m they step over every corner"),
        Bound("planner.pull_max_phi", math.radians(0.5), math.radians(90.0), "rad",
              "a pull needs a chain straight within some angle: under 0.5 deg no real chain "
              "is that straight, over 90 deg the robot cannot lead it"),
        Bound("planner.joint_margin", 0.0, math.radians(45.0), "rad",
              "more than 45 deg below the jackknife limit forbids the turns a train makes"),
    )
}
"""Scenario settings that are not FMU parameters; the scenario model checks them with
:data:`BOUNDS`."""

MAP_BOUNDS: dict[str, Bound] = {
    bound.name: bound
    for bound in (
        # Fields of map files (a map_server YAML, a DXF floor plan); the scenario's own map
        # coordinates are bounded by SCENARIO_BOUNDS["map.coordinate"], and so are the origin
        # of a map_server map and every coordinate of a floor plan.
        Bound("resolution", 1e-3, 10.0, "m",
              "no floor scan or drawing is finer than 1 mm a pixel, and at over 10 m one pixel "
              "swallows a room"),
    )
}
"""Fields of map files, named as the file names them."""

MAP_YAML_BYTES = 1 << 20
"""Largest map_server YAML file read [bytes] (1 MiB): map_saver writes about 150 bytes, and a
larger file is refused before it is parsed."""

SWEEP_MAX_TOTAL = 100_000
"""Most runs a sweep makes unless the caller raises the limit (``--max-total``); here, not in
:mod:`pushtrain.studies.sweep_spec`, so that the CLI shows it without loading the sweep."""


def check(name: str, value) -> str | None:
    """None if ``value`` is plausible for parameter ``name``, else why not.

    ``name`` is a parameter of :data:`BOUNDS`, optionally with an element index (``"mass[2]"``).
    The message names the value, the allowed range with its unit and the reason, e.g.
    ``"front[1] = 0.01: allowed 0.05 to 10 m (a hitch link shorter than 5 cm or longer than
    10 m is not a trailer)"``.

    Raises
    ------
    KeyError
        ``name`` has no bound.
    """
    base = name.split("[", 1)[0]
    try:
        bound = BOUNDS[base]
    except KeyError:
        raise KeyError(f"{name!r} has no bound; bounded parameters: {', '.join(BOUNDS)}") from None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return bound.message(name, value) + f"; got a {type(value).__name__}, not a number"
    if not bound.contains(value):
        return bound.message(name, value)
    return None


def steady_joint_angles(radius: float, front, rear) -> list[float] | None:
    """Joint angles [rad] of a train turning steadily with its last trailer's axle on a circle of
    ``radius`` [m], or None if no steady turn of that radius exists.

    ``front`` are F_1..F_n (trailer i's axle forward to its hitch), ``rear`` R_0..R_{n-1} (body
    i-1's axle, the robot's centre for i = 1, back to the hitch). In a steady turn every axle
    moves on a circle about one centre, square to its radius (no wheel slides sideways): from
    trailer i's axle radius r_i, its hitch lies at sqrt(r_i^2 + F_i^2) from the centre, body
    i-1's axle at r_{i-1} = sqrt(r_i^2 + F_i^2 - R_{i-1}^2), and joint i is bent by
    atan(F_i / r_i) + asin(R_{i-1} / sqrt(r_i^2 + F_i^2)) (2 atan(D / r) when F = R = D).
    When r_i^2 + F_i^2 < R_{i-1}^2 body i-1 cannot keep its axle square to the centre: no
    steady turn. Angles are returned for joints n..1 (last trailer first).
    """
    r = float(radius)
    angles = []
    for f, b in zip(reversed(list(front)), reversed(list(rear)), strict=True):
        hitch2 = r * r + f * f
        if hitch2 < b * b:
            return None
        angles.append(math.atan2(f, r) + math.asin(min(1.0, b / math.sqrt(hitch2))))
        r = math.sqrt(hitch2 - b * b)
    return angles


def min_turning_radius(front, rear, phi_max: float) -> float:
    """The smallest radius [m] of the last trailer's path that the train can drive steadily
    with every joint within ``phi_max`` [rad] (see :func:`steady_joint_angles`); on a tighter
    arc a joint bends past the limit (the train jackknifes) or no steady turn exists.

    ``F = R = D`` for every link gives ``D / tan(phi_max / 2)`` (0.52 m for D = 0.52 m,
    phi_max = 90 deg). Found by bisection (the angles grow as the radius shrinks) to 1e-12 of
    the radius.
    """
    def fits(r: float) -> bool:
        angles = steady_joint_angles(r, front, rear)
        return angles is not None and max(angles) <= phi_max

    hi = max(max(front), max(rear))
    while not fits(hi):
        hi *= 2.0
    lo = 0.0
    while hi - lo > 1e-12 * hi:
        mid = 0.5 * (lo + hi)
        if fits(mid):
            hi = mid
        else:
            lo = mid
    return hi
