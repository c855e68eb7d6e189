"""Planner: the whole train's motion under its controller (default ``planner = "lattice"``,
:mod:`~pushtrain.planner.lattice`), the OMPL Reeds-Shepp planners of the last trailer, the
whole-train check and the reference export.

Public API::

    World.from_dict(d), Train.uniform(n), BodyFootprint(length, width, offset)
    plan(world, start, goal, train, config=PlannerConfig(), start_headings=None) -> PlannedPath
    PlannedPath.to_reference(speed, cusp_dwell) / to_json / from_json
    check_train(world, train, start, segments, ...) -> TrainCheckResult
    PlanningError(reason, message, where)
"""

from pushtrain.errors import PLANNING_REASONS as REASONS
from pushtrain.errors import PlanningError, PlanningInputError

from . import worlds
from .config import PLANNERS, PlannerConfig, turning_radius_from_joint_limit
from .curves import ReedsSheppCurve, primitives_to_segments, rs_distance
from .path import PlannedPath
from .planner import plan
from .reeds_shepp import Primitive, evaluate_primitives, recover_primitives
from .train_check import TrackerConfig, TrainCheckResult, check_train
from .world import BodyFootprint, Train, World, draw_poses, save_diagnostic

__all__ = [
    "REASONS", "PlanningError", "PlanningInputError", "PlannedPath", "PLANNERS", "PlannerConfig",
    "ReedsSheppCurve", "plan", "primitives_to_segments", "rs_distance",
    "turning_radius_from_joint_limit", "Primitive", "evaluate_primitives", "recover_primitives",
    "TrackerConfig", "TrainCheckResult", "check_train", "BodyFootprint", "Train", "World",
    "draw_poses", "save_diagnostic", "worlds",
]
