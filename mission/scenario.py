"""Scenario files (TOML): what to plan and co-simulate, validated field by field.

Every field has a default where the paper gives one (its Table 1, :mod:`pushtrain.table1`:
42.1 kg, D = 0.52 m, 0.6 m x 0.8 m, mu = 0.09, 0.005 s; robot limits 0.1 m/s and 0.1 rad/s).
Unknown keys are errors, and all bad fields are reported at once with their path
(``train.mass[2]``), the value and what is allowed.
Angles in files are in degrees (``*_deg``); everything inside is SI and radians.

Three kinds of mission (``mission.kind``):

``plan``
    plan a path for the last trailer from ``start`` to ``goal`` through ``map`` (by default a
    search over the whole train under its controller), then co-simulate the controller
    tracking it.
``scripted``
    track a scripted line/arc reference (``reference.segments``) from ``start``.
``rotation``
    open-loop pure robot rotation (the paper's Sec. 4.4 slip experiment); no controller.
"""

from __future__ import annotations

import math
import re
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from pushtrain import defaults, table1
from pushtrain.core.controller import ControllerConfig
from pushtrain.core.governor import GovernorConfig
from pushtrain.core.sensors import SensorConfig
from pushtrain.cosim.plant import PlantConfig
from pushtrain.errors import FieldErrors, ScenarioError
from pushtrain.fmu.variables import MAX_TRAILERS
from pushtrain.limits import BOUNDS, SCENARIO_BOUNDS, min_turning_radius
from pushtrain.planner.config import PlannerConfig
from pushtrain.settings import file_section
from pushtrain.validation import (
    FiniteFloat,
    Integer,
    NonNegFloat,
    PositiveFloat,
    field_errors,
    no_bool,
    read_toml,
    validate_model,
)

__all__ = ["Scenario", "load_scenario", "parse_scenario"]

Point = Annotated[list[FiniteFloat], Field(min_length=2, max_length=2)]


class _Section(BaseModel):
    # strict: a TOML boolean or string is not a number (n = true is not 1, n = "3" is not 3)
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)


class Size(_Section):
    length: PositiveFloat
    width: PositiveFloat
    offset: FiniteFloat = 0.0


TrainSection = file_section(PlantConfig, "TrainSection", _Section, part="train", extra={
    "n": (Annotated[Integer, Field(ge=1, le=MAX_TRAILERS)], 3),
    "link": (PositiveFloat, table1.LINK),
    "front": (list[PositiveFloat] | None, None),
    "rear": (list[PositiveFloat] | None, None),
    "trailer_size": (Size, Size(length=table1.TRAILER_LENGTH, width=table1.TRAILER_WIDTH)),
    "robot_size": (Size, Size(length=defaults.ROBOT_LENGTH, width=defaults.ROBOT_WIDTH)),
})
"""``[train]``: n, the links and footprints, and the trailers' physics of
:class:`~pushtrain.cosim.plant.PlantConfig` (``mass``, ``inertia``, ``payload``, ``mu``: one
value or a list of n; ``phi_max_deg``), with the FMU's defaults (Table 1)."""

RobotSection = file_section(ControllerConfig, "RobotSection", _Section, part="robot",
                            also=((PlantConfig, "robot"),))
"""``[robot]``: the speed limits of :class:`~pushtrain.core.controller.ControllerConfig`
(``v_max``, ``w_max_deg``) and the plant's velocity loop of
:class:`~pushtrain.cosim.plant.PlantConfig` (``tau``, ``acc_max``, ``alpha_max_deg``)."""


class Pose(_Section):
    x: FiniteFloat
    y: FiniteFloat
    theta_deg: FiniteFloat = 0.0


class StartSection(Pose):
    """The last trailer's start pose (heading toward the robot) and the chain's shape."""

    joint_angles_deg: list[FiniteFloat] | None = None
    lateral_offset: FiniteFloat = 0.0
    heading_offset_deg: FiniteFloat = 0.0


class MapSection(_Section):
    """The map: polygons (``free`` outline or ``bounds``, ``obstacles``/``walls``), an occupancy
    grid (``grid``: a ROS map_server YAML file) and a CAD floor plan (``dxf`` with its
    ``layers``), in any combination; polygons are drawn on top of a grid or a floor plan. File
    paths are relative to the scenario file."""

    free: list[Point] | None = None
    bounds: Annotated[list[FiniteFloat], Field(min_length=4, max_length=4)] | None = None
    obstacles: list[list[Point]] = []
    walls: list[list[Point]] = []
    grid: Annotated[str, Field(min_length=1)] | None = None
    dxf: Annotated[str, Field(min_length=1)] | None = None
    layers: Annotated[list[Annotated[str, Field(min_length=1)]], Field(min_length=1)] | None = None
    line_thickness: PositiveFloat | None = None  # m; open lines of the DXF (default 0.05)
    dxf_units: Literal["m", "dm", "cm", "mm", "in", "ft"] | None = None  # default: $INSUNITS

    @model_validator(mode="after")
    def _files(self):
        problems = []
        if self.dxf is not None and self.layers is None:
            problems.append(("map.layers", None, "required with map.dxf: the DXF layers that "
                                                 "hold walls and obstacles, e.g. [\"WALLS\"]"))
        if self.dxf is None:
            for name in ("layers", "line_thickness", "dxf_units"):
                if getattr(self, name) is not None:
                    problems.append((f"map.{name}", getattr(self, name),
                                     "only with map.dxf (a DXF floor plan)"))
        if problems:
            raise FieldErrors("", problems)
        return self


PlannerSection = file_section(PlannerConfig, "PlannerSection", _Section)
"""``[planner]``: the file settings of :class:`~pushtrain.planner.config.PlannerConfig`, with its
defaults (``planner``: "lattice", the whole-train closed-loop search; the others: OMPL on the
last trailer)."""


class SegmentSpec(_Section):
    kind: Literal["line", "arc"]
    length: PositiveFloat
    radius: PositiveFloat | None = None
    turn: Literal["left", "right"] | None = None
    direction: Literal["push", "pull"] = "push"
    speed: PositiveFloat | None = None

    @model_validator(mode="after")
    def _arc_fields(self):
        if self.kind == "arc" and (self.radius is None or self.turn is None):
            raise ValueError("an arc needs 'radius' and 'turn' ('left' or 'right')")
        if self.kind == "line" and (self.radius is not None or self.turn is not None):
            raise ValueError("a line takes no 'radius' or 'turn'")
        return self


class ReferenceSection(_Section):
    speed: PositiveFloat = defaults.REFERENCE_SPEED
    cusp_dwell: NonNegFloat = defaults.CUSP_DWELL
    segments: Annotated[list[SegmentSpec], Field(min_length=1)]


ControllerSection = file_section(ControllerConfig, "ControllerSection", _Section, extra={
    # the controller's own D (None: the plant's links)
    "model_link": (PositiveFloat | None, None),
    # slip-aware governor: limit command changes so the predicted lateral wheel forces stay
    # below governor_fraction of friction (computed with the controller's own model of the train)
    "governor": (bool, False),
    "governor_fraction": (Annotated[float, Field(gt=0, le=1)], GovernorConfig.fraction),
})
"""``[controller]``: the gains and rate limits of
:class:`~pushtrain.core.controller.ControllerConfig` (the paper keeps |alpha| <= 10 deg/s² to
avoid lateral slip, Sec. 4.4), the controller's own link and the governor."""


SensorSection = file_section(SensorConfig, "SensorSection", _Section)
"""``[sensors]``: the file settings of :class:`~pushtrain.core.sensors.SensorConfig`, with its
defaults (``localize``: "robot" computes the last trailer from the joint angles, as the paper's
prototype; "last_trailer" localizes it directly, the setting of Eq. 6-9)."""


class EventSpec(_Section):
    type: Literal["push", "slide", "bias"]
    t: NonNegFloat
    duration: PositiveFloat | None = None
    lateral: FiniteFloat = 0.0
    fx: FiniteFloat = 0.0
    fy: FiniteFloat = 0.0
    distance: FiniteFloat | None = None
    trailer: Annotated[Integer, Field(ge=1)] | None = None
    joint: Annotated[Integer, Field(ge=1)] | None = None
    bias_deg: FiniteFloat | None = None

    @model_validator(mode="after")
    def _fields_for_type(self):
        if self.type in ("push", "slide") and self.duration is None:
            raise ValueError(f"a {self.type} event needs 'duration' (s, > 0)")
        if self.type == "slide" and self.distance is None:
            raise ValueError("a slide event needs 'distance' (m, lateral)")
        if self.type == "bias" and (self.joint is None or self.bias_deg is None):
            raise ValueError("a bias event needs 'joint' (1..n) and 'bias_deg'")
        return self


class RotationSection(_Section):
    w_max_deg: PositiveFloat = 20.0
    alpha_deg: PositiveFloat = 5.0
    hold: NonNegFloat = 0.0
    duration: PositiveFloat = 30.0


FmuSection = file_section(PlantConfig, "FmuSection", _Section, part="fmu", extra={
    # 2: an FMI 2.0 FMU built for train.n (cached per n); 3: the one FMI 3.0 FMU, n set at start
    "fmi_version": (Annotated[Literal[2, 3], no_bool("2 or 3")], 2),
})
"""``[fmu]``: the plant's ``slip_mode`` and ``max_substep`` (:class:`~pushtrain.cosim.plant.
PlantConfig`) and which FMI version runs it."""


class SimSection(_Section):
    step: PositiveFloat = table1.SAMPLING_TIME
    horizon: PositiveFloat | None = None
    settle_time: NonNegFloat = defaults.SETTLE_TIME
    goal_tolerance: PositiveFloat = defaults.GOAL_TOLERANCE[0]
    goal_heading_tolerance_deg: PositiveFloat = defaults.GOAL_HEADING_TOLERANCE_DEG


class MissionSection(_Section):
    kind: Literal["plan", "scripted", "rotation"] = "plan"


class Scenario(_Section):
    """A whole scenario file."""

    name: str = "scenario"
    description: str = ""
    seed: Annotated[Integer, Field(ge=1)] = 1
    mission: MissionSection = MissionSection()
    train: TrainSection = TrainSection()
    robot: RobotSection = RobotSection()
    map: MapSection | None = None
    start: StartSection | None = None
    goal: Pose | None = None
    planner: PlannerSection = PlannerSection()
    reference: ReferenceSection | None = None
    rotation: RotationSection = RotationSection()
    controller: ControllerSection = ControllerSection()
    sensors: SensorSection = SensorSection()
    events: list[EventSpec] = []
    fmu: FmuSection = FmuSection()
    sim: SimSection = SimSection()

    @model_validator(mode="after")
    def _consistent(self):
        problems = []
        n = self.train.n
        for name in ("front", "rear"):
            values = getattr(self.train, name)
            if values is not None and len(values) != n:
                problems.append((f"train.{name}", values, f"a list of n = {n} lengths"))
        for name in ("mass", "inertia", "payload", "mu"):
            values = getattr(self.train, name)
            if isinstance(values, list) and len(values) != n:
                problems.append((f"train.{name}", values, f"one value or a list of n = {n}"))
        clearance = self.planner.clearance
        if isinstance(clearance, list) and len(clearance) != n + 1:
            problems.append(("planner.clearance", clearance,
                             f"one value or a list of n + 1 = {n + 1} (robot, trailers 1..{n})"))
        bias = self.sensors.joint_bias_deg
        if isinstance(bias, list) and len(bias) != n:
            problems.append(("sensors.joint_bias_deg", bias, f"one value or a list of n = {n}"))
        if self.start is not None and self.start.joint_angles_deg is not None:
            if len(self.start.joint_angles_deg) != n:
                problems.append(("start.joint_angles_deg", self.start.joint_angles_deg,
                                 f"a list of n = {n} angles"))
            else:
                problems += _start_joints(self)
        for k, ev in enumerate(self.events):
            if ev.trailer is not None and ev.trailer > n:
                problems.append((f"events[{k}].trailer", ev.trailer, f"1..{n}"))
            if ev.joint is not None and ev.joint > n:
                problems.append((f"events[{k}].joint", ev.joint, f"1..{n}"))
        problems += _implausible(self)
        problems += _inconsistent_run(self)
        problems += _turning_radius(self)
        problems += _run_length(self)
        kind = self.mission.kind
        if kind == "plan":
            for name in ("map", "start", "goal"):
                if getattr(self, name) is None:
                    problems.append((name, None, "required when mission.kind = 'plan'"))
            m = self.map
            if m is not None and all(v is None for v in (m.free, m.bounds, m.grid, m.dxf)):
                problems.append(("map", "no free/bounds/grid/dxf",
                                 "give 'free' (outline), 'bounds', 'grid' (a map_server YAML "
                                 "file) or 'dxf' (a floor plan)"))
        elif kind == "scripted":
            if self.reference is None:
                problems.append(("reference", None, "required when mission.kind = 'scripted'"))
            if self.start is None:
                problems.append(("start", None, "required when mission.kind = 'scripted'"))
        if problems:
            raise FieldErrors("", problems)
        return self


class _OutOfRange(tuple):
    """A problem (where, value, allowed) of one value against its own plausible range: it holds
    whatever the scenario's other fields are (see :func:`parse_scenario`)."""


def _bound_problem(where: str, bound_name: str, value, deg: bool = False):
    """(where, value, allowed) if ``value`` is outside the plausible range of ``bound_name``
    (:data:`pushtrain.limits.BOUNDS`); ``deg``: the field is in degrees, the bound in radians."""
    bound = BOUNDS.get(bound_name) or SCENARIO_BOUNDS[bound_name]
    lo, hi, unit = bound.lo, bound.hi, bound.unit
    if deg:
        lo, hi, unit = math.degrees(lo), math.degrees(hi), unit.replace("rad", "deg")
    if lo <= value <= hi:
        return None
    unit = f" {unit}" if unit else ""
    return _OutOfRange((where, value, f"allowed {lo:.6g} to {hi:.6g}{unit} ({bound.reason})"))


def _per_trailer_values(where: str, value):
    if isinstance(value, list):
        return [(f"{where}[{k}]", v) for k, v in enumerate(value)]
    return [(where, value)]


def _implausible(sc: "Scenario") -> list[tuple[str, object, str]]:
    """Values that validate as numbers but are not a train, a robot or a run this tool models:
    each against its range in :data:`pushtrain.limits.BOUNDS` (shared with the FMU)."""
    t, r = sc.train, sc.robot
    checks = [("train.link", "front", t.link)]
    for name in ("front", "rear"):
        values = getattr(t, name) or []
        checks += [(w, name, v) for w, v in _per_trailer_values(f"train.{name}", values)]
    for name in ("mass", "inertia", "payload", "mu"):
        checks += [(w, name, v) for w, v in _per_trailer_values(f"train.{name}", getattr(t, name))]
    for body in ("trailer_size", "robot_size"):
        size = getattr(t, body)
        checks += [(f"train.{body}.length", "body.size", size.length),
                   (f"train.{body}.width", "body.size", size.width)]
    checks += [("robot.tau", "robot_tau", r.tau), ("robot.acc_max", "robot_acc_max", r.acc_max),
               ("robot.v_max", "robot.v_max", r.v_max),
               ("fmu.max_substep", "max_substep", sc.fmu.max_substep),
               ("sim.step", "sim.step", sc.sim.step)]
    checks += [(f"controller.{k}", "controller.gain", getattr(sc.controller, k))
               for k in ("k_x", "k_y", "k_theta")]
    if sc.controller.model_link is not None:
        checks.append(("controller.model_link", "front", sc.controller.model_link))
    if sc.sim.horizon is not None:
        checks.append(("sim.horizon", "sim.horizon", sc.sim.horizon))
    problems = [_bound_problem(*c) for c in checks]
    problems += [
        _bound_problem("robot.alpha_max_deg", "robot_alpha_max", r.alpha_max_deg, deg=True),
        _bound_problem("robot.w_max_deg", "robot.w_max", r.w_max_deg, deg=True),
        _bound_problem("train.phi_max_deg", "phi_max", t.phi_max_deg, deg=True),
        _bound_problem("rotation.w_max_deg", "rotation.w_max", sc.rotation.w_max_deg, deg=True),
        _bound_problem("rotation.alpha_deg", "rotation.alpha", sc.rotation.alpha_deg, deg=True),
        _bound_problem("rotation.hold", "rotation.hold", sc.rotation.hold),
    ]
    problems += [_bound_problem(w, "map.coordinate", v) for w, v in _coordinates(sc)]
    problems += [_bound_problem(w, "planner.clearance", v)
                 for w, v in _per_trailer_values("planner.clearance", sc.planner.clearance)]
    problems += [_bound_problem("planner.step_length", "planner.step_length",
                                sc.planner.step_length),
                 _bound_problem("planner.pull_max_phi_deg", "planner.pull_max_phi",
                                sc.planner.pull_max_phi_deg, deg=True),
                 _bound_problem("planner.joint_margin_deg", "planner.joint_margin",
                                sc.planner.joint_margin_deg, deg=True)]
    if (sc.mission.kind == "plan" and sc.planner.planner == "lattice"
            and sc.planner.joint_margin_deg >= t.phi_max_deg):
        problems.append(("planner.joint_margin_deg", sc.planner.joint_margin_deg,
                         f"less than train.phi_max_deg = {t.phi_max_deg:g} (the search keeps "
                         "every joint within phi_max minus this margin)"))
    return [p for p in problems if p is not None]


def _coordinates(sc: "Scenario"):
    """Every map and pose coordinate [m] with its scenario path."""
    if sc.map is not None:
        for key in ("free", "obstacles", "walls"):
            value = getattr(sc.map, key) or []
            rings = [value] if key == "free" else value
            for i, ring in enumerate(rings):
                prefix = f"map.{key}" if key == "free" else f"map.{key}[{i}]"
                for j, point in enumerate(ring):
                    for c, v in zip("xy", point, strict=True):
                        yield f"{prefix}[{j}].{c}", v
        for k, v in enumerate(sc.map.bounds or []):
            yield f"map.bounds[{k}]", v
    for name in ("start", "goal"):
        pose = getattr(sc, name)
        if pose is not None:
            yield f"{name}.x", pose.x
            yield f"{name}.y", pose.y


def _inconsistent_run(sc: "Scenario") -> list[tuple[str, object, str]]:
    """Combinations the co-simulation would refuse only when it starts."""
    problems = []
    if sc.fmu.slip_mode == 1:
        for k, ev in enumerate(sc.events):
            if ev.type == "slide":
                problems.append((f"events[{k}].type", ev.type,
                                 "a slide event imposes a kinematic slide, which needs "
                                 "fmu.slip_mode = 0; with slip_mode = 1 the wheels slide "
                                 "physically: use a push event"))
    horizon, step = sc.sim.horizon, sc.sim.step
    ratio = None if horizon is None else horizon / step
    # (a horizon too long for the step is the bounds check's to report)
    if ratio is not None and math.isfinite(ratio) and \
            abs(ratio - round(ratio)) > 1e-9 * max(1.0, ratio):
        problems.append(("sim.horizon", horizon,
                         f"a whole number of steps of sim.step = {step:g} s "
                         f"(e.g. {step * max(1, round(horizon / step)):g} s)"))
    return problems


def _start_joints(sc: "Scenario") -> list[tuple[str, object, str]]:
    """Start joint angles beyond the joint limit: the FMU reports a jackknife at t = 0."""
    limit = sc.train.phi_max_deg
    return [(f"start.joint_angles_deg[{k}]", a,
             f"within -{limit:g} to {limit:g} deg (train.phi_max_deg): a joint bent further "
             "is jackknifed before the run starts")
            for k, a in enumerate(sc.start.joint_angles_deg) if abs(a) > limit]


def _links(sc: "Scenario") -> tuple[list[float], list[float]] | None:
    """The train's F_1..F_n and R_0..R_{n-1} [m], None if their lists do not fit n."""
    t = sc.train
    front = t.front if t.front is not None else [t.link] * t.n
    rear = t.rear if t.rear is not None else [t.link] * t.n
    return (front, rear) if len(front) == len(rear) == t.n else None


def _turning_radius(sc: "Scenario") -> list[tuple[str, object, str]]:
    """A planner turning radius the train cannot drive: on a tighter arc than
    :func:`pushtrain.limits.min_turning_radius` a joint bends past train.phi_max_deg."""
    radius, links = sc.planner.turning_radius, _links(sc)
    if radius is None or links is None:
        return []
    phi_max = math.radians(sc.train.phi_max_deg)
    smallest = min_turning_radius(*links, phi_max)
    if radius >= smallest * (1.0 - 1e-9):
        return []
    longest = max(max(links[0]), max(links[1]))
    rule = longest / math.tan(phi_max / (2.0 * (1.0 + sc.planner.transient_margin)))
    return [("planner.turning_radius", radius,
             f"at least {smallest:.4g} m for this train: on a tighter arc a joint bends past "
             f"train.phi_max_deg = {sc.train.phi_max_deg:g} deg (the steady turn of its links "
             f"train.front/rear/link); leave it out for the planner's rule, {rule:.4g} m")]


def _reference_times(ref: "ReferenceSection") -> list[tuple[float, float, float]]:
    """(speed [m/s], duration [s], end time [s]) of each scripted segment: the times of
    :class:`~pushtrain.core.reference.Reference` (a cusp dwell at each direction change)."""
    out, t, previous = [], 0.0, None
    for seg in ref.segments:
        if previous is not None and seg.direction != previous:
            t += ref.cusp_dwell
        speed = seg.speed if seg.speed is not None else ref.speed
        t += seg.length / speed
        out.append((speed, seg.length / speed, t))
        previous = seg.direction
    return out


def _run_length(sc: "Scenario") -> list[tuple[str, object, str]]:
    """A run longer than a day, from the fields that make its length when ``sim.horizon`` is
    not set (a scripted reference's segments, sim.settle_time, rotation.duration), and events
    at or after the latest end the run can have.

    That end is the mission's own (the reference's end plus sim.settle_time, the rotation's
    duration; a planned path's is known only after planning: a day at most), or sim.horizon
    if that is later. A sim.horizon that ends the run before an event (a quick look at the
    start of a run) is allowed: the co-simulation logs that the event never comes."""
    limit = SCENARIO_BOUNDS["sim.horizon"].hi
    problems = []
    kind, settle, horizon = sc.mission.kind, sc.sim.settle_time, sc.sim.horizon
    if kind == "rotation":
        end, why = sc.rotation.duration, f"rotation.duration = {sc.rotation.duration:g} s"
        if horizon is None and end > limit:
            problems.append(("rotation.duration", end,
                             f"at most {limit:g} s, the longest a run may last (a rotation runs "
                             "for rotation.duration when sim.horizon is not set)"))
    elif kind == "scripted" and sc.reference is not None:
        times = _reference_times(sc.reference)
        reference_end = times[-1][2]
        end = reference_end + settle
        why = f"the reference's {reference_end:.6g} s plus sim.settle_time = {settle:g} s"
        if horizon is None:
            problems += _long_reference(sc, times, limit)
    else:  # a planned path sets the run's length
        end, why = limit, "the longest a run may last; the planned path sets the run's length"
    if horizon is not None and horizon > end:
        end, why = horizon, f"sim.horizon = {horizon:g} s"
    if end > limit:
        end, why = limit, "the longest a run may last"
    for k, ev in enumerate(sc.events):
        if ev.t >= end:
            problems.append((f"events[{k}].t", ev.t,
                             f"before the run ends at {end:.6g} s ({why}): an event then or "
                             "later never happens"))
    return problems


def _long_reference(sc: "Scenario", times, limit: float) -> list[tuple[str, object, str]]:
    """The segment, or sim.settle_time, that makes a scripted run longer than ``limit`` [s]
    (its horizon when sim.horizon is not set: the reference's end plus the settling)."""
    problems = []
    segments, settle = sc.reference.segments, sc.sim.settle_time
    reference_end = times[-1][2]
    long_ones = [k for k, (_, d, _) in enumerate(times) if d > limit]
    for k in long_ones:
        speed, duration, _ = times[k]
        problems.append((f"reference.segments[{k}].length", segments[k].length,
                         f"at {speed:g} m/s it takes {duration:.6g} s, more than the "
                         f"{limit:g} s a run may last"))
    if not long_ones and reference_end > limit:
        k = next(k for k, (_, _, t) in enumerate(times) if t > limit)
        problems.append((f"reference.segments[{k}].length", segments[k].length,
                         f"the reference reaches {times[k][2]:.6g} s by the end of this "
                         "segment (each at its speed, with the cusp dwells), more than the "
                         f"{limit:g} s a run may last"))
    elif reference_end <= limit < reference_end + settle:
        problems.append(("sim.settle_time", settle,
                         f"the reference takes {reference_end:.6g} s; with {settle:g} s to "
                         f"settle the run would last {reference_end + settle:.6g} s, more than "
                         f"the {limit:g} s a run may last"))
    return problems


def parse_scenario(data: dict, source: str = "<scenario>") -> Scenario:
    """Validate plain data (a parsed TOML document) into a :class:`Scenario`.

    Every bad field is reported at once: the checks of whole values against their plausible
    ranges (``sim.step = 5``) run on a model, which fields of the wrong type or schema range
    prevent; so the fields refused are left at their defaults and the rest checked again, and
    the values out of their own range are reported too (the checks that combine fields are
    not: a default could make them say what the file does not)."""
    try:
        return validate_model(Scenario, data, source, ScenarioError)
    except ScenarioError as exc:
        more = _out_of_range_beside(data, exc.errors)
        if not more:
            raise
        raise ScenarioError(source, [*exc.errors, *more]) from None


def _out_of_range_beside(data: dict, problems: list) -> list:
    """The values out of their own range (:class:`_OutOfRange`) in ``data`` once the fields of
    ``problems`` are removed (left at their defaults), not already among ``problems``."""
    import copy

    from pydantic import ValidationError

    rest = copy.deepcopy(data)
    for where, _, _ in problems:
        keys = [k for k in re.split(r"\.", re.sub(r"\[\d+\]", "", str(where))) if k]
        node = rest
        for key in keys[:-1]:
            node = node.get(key) if isinstance(node, dict) else None
        if keys and isinstance(node, dict):
            node.pop(keys[-1], None)
    try:
        Scenario.model_validate(rest)
    except ValidationError as exc:
        said = {where for where, _, _ in problems}
        return [p for p in field_errors(exc) if isinstance(p, _OutOfRange) and p[0] not in said]
    except Exception:  # noqa: BLE001, S110 - a second look only: the problems found stand
        pass            # alone, whatever the defaults left for the fields refused make of it
    return []


def load_scenario(path) -> Scenario:
    """Read and validate a scenario TOML file; the map's file paths (``map.grid``, ``map.dxf``)
    are made absolute against the scenario file's folder."""
    from pathlib import Path

    data = read_toml(path, ScenarioError)
    section = data.get("map")
    if isinstance(section, dict):
        for key in ("grid", "dxf"):
            value = section.get(key)
            if isinstance(value, str) and value:
                file = Path(value).expanduser()
                section[key] = str(file if file.is_absolute()
                                   else Path(path).resolve().parent / file)
    return parse_scenario(data, str(path))
