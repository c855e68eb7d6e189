"""From a validated :class:`~pushtrain.mission.scenario.Scenario` to plans, runs and result folders.

Library code for the CLI: it raises typed errors and logs, it never prints or exits.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import NamedTuple

import numpy as np

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.kinematics import ChainGeometry
from pushtrain.core.openloop import RotationProfile
from pushtrain.core.reference import Reference
from pushtrain.core.segment import PULL, PUSH, Segment
from pushtrain.core.sensors import SensorConfig
from pushtrain.cosim.events import Push, SetBias, Slide
from pushtrain.cosim.master import simulate
from pushtrain.cosim.plant import InitialState, PlantConfig
from pushtrain.cosim.result import Result
from pushtrain.errors import ScenarioError
from pushtrain.fmu.build import build_fmu
from pushtrain.settings import config_values

from .scenario import Scenario

__all__ = ["train_of", "plant_of", "controller_of", "sensors_of", "goal_tolerance_of", "events_of",
           "scripted_reference", "plan_path", "fmu_build_args", "run_scenario"]

log = logging.getLogger(__name__)


def _per_trailer(value, n: int) -> np.ndarray:
    return np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()


def geometry_of(sc: Scenario) -> ChainGeometry:
    """The plant's hitch geometry from ``train`` (``front``/``rear`` lists or one ``link``)."""
    n = sc.train.n
    front = sc.train.front if sc.train.front is not None else [sc.train.link] * n
    rear = sc.train.rear if sc.train.rear is not None else [sc.train.link] * n
    return ChainGeometry(np.array(front, float), np.array(rear, float))


class BiasModel(NamedTuple):
    """What the closed-form offset analysis (:mod:`pushtrain.core.analysis`) takes from a
    scenario: the controller's link [m], the reference speed [m/s], the joint biases (n,)
    [rad] and their effective (alternating) sum [rad]."""

    link: float
    speed: float
    bias: np.ndarray
    eps: float


def bias_model(sc: Scenario) -> BiasModel:
    """The :class:`BiasModel` of ``sc`` (the ``analyze`` command and the sweeps' predictions)."""
    from pushtrain.core import analysis

    link = sc.controller.model_link or sc.train.link
    speed = sc.reference.speed if sc.reference is not None else sc.planner.speed
    bias = np.radians(_per_trailer(sc.sensors.joint_bias_deg, sc.train.n))
    return BiasModel(link, speed, bias, analysis.effective_bias(bias))


def train_of(sc: Scenario):
    """The planner's :class:`~pushtrain.planner.train.Train` (geometry, footprints, joint limit)."""
    from pushtrain.planner.train import BodyFootprint, Train

    t = sc.train
    trailer = BodyFootprint(t.trailer_size.length, t.trailer_size.width, t.trailer_size.offset)
    robot = BodyFootprint(t.robot_size.length, t.robot_size.width, t.robot_size.offset)
    return Train(geometry_of(sc), robot, (trailer,) * t.n, math.radians(t.phi_max_deg))


def plant_of(sc: Scenario) -> PlantConfig:
    """The plant FMU's parameters: the links, and the ``[train]``, ``[robot]`` and ``[fmu]``
    settings of :class:`~pushtrain.cosim.plant.PlantConfig`."""
    geom = geometry_of(sc)
    return PlantConfig(sc.train.n, front=geom.front, rear=geom.rear,
                       **config_values(PlantConfig, sc.train, part="train"),
                       **config_values(PlantConfig, sc.robot, part="robot"),
                       **config_values(PlantConfig, sc.fmu, part="fmu"))


def controller_of(sc: Scenario) -> ControllerConfig:
    """Gains, robot limits and the controller's own chain model (``model_link`` or the plant's)."""
    c = sc.controller
    if c.model_link is None:
        geom = geometry_of(sc)
    else:
        geom = ChainGeometry.uniform(sc.train.n, c.model_link)
    return ControllerConfig(geom, **config_values(ControllerConfig, sc.controller),
                            **config_values(ControllerConfig, sc.robot, part="robot"))


def governed(sc: Scenario, config: ControllerConfig):
    """The compiled control law behind a slip-aware governor built from the scenario's train."""
    from pushtrain.core.controller import Controller
    from pushtrain.core.governor import GovernedController, GovernorConfig, SlipGovernor

    n, plant = sc.train.n, plant_of(sc)
    gov = SlipGovernor(GovernorConfig(
        config.geometry, _per_trailer(plant.mass, n) + _per_trailer(plant.payload, n),
        _per_trailer(plant.inertia, n), _per_trailer(plant.mu, n),
        fraction=sc.controller.governor_fraction,
        tau=plant.robot_tau, acc_max=plant.robot_acc_max, alpha_max=plant.robot_alpha_max))
    return GovernedController(Controller(config), gov, dt=sc.sim.step)


def goal_tolerance_of(sc: Scenario) -> tuple[float, float]:
    """The co-simulation's goal test, ``[sim]``'s tolerances [m, rad]: the planner plans to it
    and the master stops on it."""
    return (sc.sim.goal_tolerance, math.radians(sc.sim.goal_heading_tolerance_deg))


def sensors_of(sc: Scenario) -> SensorConfig:
    """The co-simulation's sensor model: the ``[sensors]`` section for ``train.n`` joints, its
    noise seeded by the scenario's ``seed``."""
    return SensorConfig(sc.train.n, **config_values(SensorConfig, sc.sensors), seed=sc.seed)


def events_of(sc: Scenario) -> list:
    out = []
    for ev in sc.events:
        if ev.type == "push":
            out.append(Push(ev.t, ev.duration, ev.lateral, ev.fx, ev.fy))
        elif ev.type == "slide":
            out.append(Slide(ev.t, ev.duration, ev.distance, ev.trailer))
        else:
            out.append(SetBias(ev.t, ev.joint, math.radians(ev.bias_deg)))
    return out


def _start_pose(sc: Scenario) -> tuple[float, float, float]:
    return (sc.start.x, sc.start.y, math.radians(sc.start.theta_deg))


def scripted_reference(sc: Scenario) -> Reference:
    """The scripted line/arc reference of a ``scripted`` mission."""
    segments = []
    for spec in sc.reference.segments:
        curvature = 0.0
        if spec.kind == "arc":
            curvature = (1.0 if spec.turn == "left" else -1.0) / spec.radius
        segments.append(Segment(spec.kind, spec.length, curvature,
                                PUSH if spec.direction == "push" else PULL, spec.speed))
    return Reference.from_segments(_start_pose(sc), segments, speed=sc.reference.speed,
                                   cusp_dwell=sc.reference.cusp_dwell)


_WORLDS: dict = {}
"""Worlds built by :func:`world_of`, by map section and file versions (a grid or floor plan is
read and traced once per process, not once per use)."""


def world_of(sc: Scenario):
    """The planner's :class:`~pushtrain.facility.free_space.World` of ``sc.map`` (None without one).

    Raises ScenarioError naming the field (``map.grid (warehouse.yaml) resolution``, ...) when a
    map file cannot be used, PlanningInputError for a malformed polygon."""
    m = sc.map
    if m is None:  # no map: the planner (OMPL) is not imported
        return None
    from pushtrain.errors import MapError
    from pushtrain.facility.loading import map_world

    files = [Path(f) for f in (m.grid, m.dxf) if f is not None]
    stamps = tuple((str(f), f.stat().st_mtime_ns if f.is_file() else None) for f in files)
    key = (m.model_dump_json(), stamps)
    world = _WORLDS.get(key)
    if world is None:
        try:
            world = map_world(free=m.free, bounds=m.bounds, obstacles=m.obstacles, walls=m.walls,
                              grid=m.grid, dxf=m.dxf, layers=m.layers or (),
                              line_thickness=m.line_thickness, dxf_units=m.dxf_units)
        except MapError as exc:
            raise ScenarioError(sc.name, [(f"map.{where}", value, allowed)
                                          for where, value, allowed in exc.errors]) from None
        if len(_WORLDS) >= 4:
            _WORLDS.pop(next(iter(_WORLDS)))
        _WORLDS[key] = world
    return world


def _start_headings(sc: Scenario) -> np.ndarray:
    """Headings of robot and trailers at the start: the last trailer's heading plus the joints."""
    n = sc.train.n
    th_n = math.radians(sc.start.theta_deg)
    angles = sc.start.joint_angles_deg
    phi = np.zeros(n) if angles is None else np.radians(angles)
    return th_n + np.concatenate((np.cumsum(phi[::-1])[::-1], [0.0]))


def _planner_args(sc: Scenario) -> tuple:
    """(world, start, goal, train, config) of :func:`~pushtrain.planner.planner.plan` for a
    ``plan`` mission, and its start headings."""
    from pushtrain.planner.config import PlannerConfig

    config = PlannerConfig(
        **config_values(PlannerConfig, sc.planner), seed=sc.seed, controller=controller_of(sc),
        goal_tolerance=goal_tolerance_of(sc),
    )
    goal = (sc.goal.x, sc.goal.y, math.radians(sc.goal.theta_deg))
    return (world_of(sc), _start_pose(sc), goal, train_of(sc), config), _start_headings(sc)


def plan_path(sc: Scenario):
    """Plan the last trailer's path of a ``plan`` mission (raises PlanningError).

    The whole-train check simulates the scenario's own controller at the reference speed and
    cusp dwell the co-simulation will use.
    """
    from pushtrain.planner.planner import plan

    args, headings = _planner_args(sc)
    return plan(*args, start_headings=headings)


def check_plan(sc: Scenario) -> None:
    """The checks :func:`plan_path` makes before it searches, without searching (raises their
    PlanningError): a start or goal that misses its clearance, a goal proven unreachable."""
    from pushtrain.planner.planner import check_mission

    args, headings = _planner_args(sc)
    check_mission(*args, start_headings=headings)


def initial_of(sc: Scenario, reference: Reference | None) -> InitialState:
    geom = geometry_of(sc)
    if sc.mission.kind == "rotation":
        if sc.start is None:
            theta = np.zeros(sc.train.n + 1)
            return InitialState(0.0, 0.0, theta)
        theta = _start_headings(sc)
        from pushtrain.core.kinematics import body_positions

        xs, ys = body_positions(sc.start.x, sc.start.y, theta, geom, from_last=True)
        return InitialState(float(xs[0]), float(ys[0]), theta)
    joints = None if sc.start.joint_angles_deg is None else np.radians(sc.start.joint_angles_deg)
    return InitialState.behind_reference(
        reference, geom, lateral_offset=sc.start.lateral_offset,
        heading_offset=math.radians(sc.start.heading_offset_deg), joint_angles=joints)


def fmu_build_args(sc: Scenario) -> dict:
    """:func:`~pushtrain.fmu.build.build_fmu`'s arguments for ``sc``'s FMU: FMI 2.0 built for
    ``train.n``, or the FMI 3.0 FMU that serves every n."""
    if sc.fmu.fmi_version == 2:
        return {"n_trailers": sc.train.n, "fmi_version": 2}
    return {"fmi_version": 3}


def run_scenario(sc: Scenario, out_dir: Path | None = None, *, reference: Reference | None = None,
                 progress: bool | None = None, fmu=None, csv: bool = False) -> Result:
    """Co-simulate ``sc`` along ``reference`` (or its scripted reference / the rotation profile).

    ``fmu`` is the TrailerTrain FMU to use (default: ``[fmu] fmi_version`` 2 builds one for
    ``train.n``, 3 takes the FMI 3.0 FMU that serves every n). With ``out_dir``, writes the
    results there (:meth:`~pushtrain.cosim.result.Result.save`: ``results.npz``,
    ``summary.json`` and, with ``csv``, ``results.csv``); without, writes nothing. The
    recorded motion is checked against the map
    (status ``collision`` if a body leaves it).
    """
    if fmu is None:
        fmu = build_fmu(**fmu_build_args(sc))
    plant = plant_of(sc)
    if sc.mission.kind == "rotation":
        rot = sc.rotation
        controller = RotationProfile(sc.train.n, math.radians(rot.w_max_deg),
                                     math.radians(rot.alpha_deg), rot.hold)
        horizon = sc.sim.horizon or rot.duration
        reference = None
    else:
        if reference is None:
            reference = scripted_reference(sc)
        controller = controller_of(sc)
        if sc.controller.governor:
            controller = governed(sc, controller)
        horizon = sc.sim.horizon
    initial = initial_of(sc, reference)
    result = simulate(
        fmu, reference, controller, sensors_of(sc), events_of(sc), plant=plant, initial=initial,
        step=sc.sim.step, horizon=horizon, settle_time=sc.sim.settle_time,
        goal_tolerance=goal_tolerance_of(sc),
        progress=progress,
    )
    result.summary["scenario"] = sc.name
    result.summary["mission"] = sc.mission.kind
    clearance = check_run_clearance(sc, result.data)
    if clearance is not None:
        result.summary["map_check"] = clearance
        if clearance["collisions"] and result.status != "fmu_error":
            first = min(clearance["collisions"].items(), key=lambda kv: kv[1]["t"])
            result.status = "collision"
            result.message = (f"{first[0]} leaves the free space at t = {first[1]['t']:.2f} s "
                              f"near ({first[1]['x']:.2f}, {first[1]['y']:.2f}) m; "
                              f"the run itself ended: {result.message}")
            result.summary["status"], result.summary["message"] = result.status, result.message
    if out_dir is not None:
        result.save(out_dir, csv=csv)
    return result


def check_run_clearance(sc: Scenario, data, resolution: float = 0.01) -> dict | None:
    """Check every body's footprint along the co-simulated motion against the map.

    Samples are taken so that no body moves more than ``resolution`` [m] (plus half a footprint
    rotation) between checks. Returns ``None`` without a map, else a dict with the first contact
    of each body (time, position) and the smallest clearance to the walls [m].
    """
    import shapely

    world = world_of(sc)
    if world is None or len(data) == 0:
        return None
    train = train_of(sc)
    n = sc.train.n
    xs = np.column_stack([data[f"x{i}"] for i in range(n + 1)])
    ys = np.column_stack([data[f"y{i}"] for i in range(n + 1)])
    ths = np.column_stack([data[f"theta{i}"] for i in range(n + 1)])
    reach = max(max(b.length, b.width) for b in train.bodies)
    motion = np.max(np.hypot(np.diff(xs, axis=0), np.diff(ys, axis=0))
                    + 0.5 * reach * np.abs(np.diff(ths, axis=0)), axis=1)
    keep = [0]
    travelled = 0.0
    for k, step in enumerate(motion, start=1):
        travelled += step
        if travelled >= resolution:
            keep.append(k)
            travelled = 0.0
    if keep[-1] != len(data) - 1:
        keep.append(len(data) - 1)
    keep = np.array(keep)
    first_contact, clearance = {}, np.inf
    for i, body in enumerate(train.bodies):
        polys = body.polygons(xs[keep, i], ys[keep, i], ths[keep, i])
        inside = shapely.covers(world.free, polys)
        clearance = min(clearance, float(np.min(world.wall_distance(polys))))
        bad = np.flatnonzero(~inside)
        if bad.size:
            k = keep[bad[0]]
            name = "robot" if i == 0 else f"trailer {i}"
            first_contact[name] = {"t": float(data["t"][k]), "x": float(xs[k, i]),
                                   "y": float(ys[k, i])}
    return {"collisions": first_contact, "min_clearance_m": 0.0 if first_contact else clearance,
            "checked_samples": int(keep.size)}


def check_start_in_map(sc: Scenario) -> None:
    """Raise ScenarioError when the map's files cannot be used, or the start or goal lies
    outside the free space of the map (on a grid: outside the image or on a cell that is not
    free)."""
    world = world_of(sc)
    if world is None:
        return
    problems = []
    grid = world.occupancy
    for name, pose in (("start", sc.start), ("goal", sc.goal)):
        if pose is None:
            continue
        if grid is not None:  # the cell under the pose, named by its image pixel
            why = grid.why_blocked(pose.x, pose.y)
            if why is not None:
                problems.append((name, f"({pose.x}, {pose.y})",
                                 f"must lie on a free cell of the map: {why}"))
        elif (why := world.why_not_free(pose.x, pose.y)) is not None:
            problems.append((name, f"({pose.x}, {pose.y})",
                             f"must lie in the map's free space: {why}"))
    if problems:
        raise ScenarioError(sc.name, problems)
