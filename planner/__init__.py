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

_EXPORTS = {
    "worlds": None,
    "PLANNERS": "config", "PlannerConfig": "config", "turning_radius_from_joint_limit": "config",
    "ReedsSheppCurve": "curves", "primitives_to_segments": "curves", "rs_distance": "curves",
    "PlannedPath": "path",
    "plan": "planner",
    "Primitive": "reeds_shepp", "evaluate_primitives": "reeds_shepp",
    "recover_primitives": "reeds_shepp",
    "TrackerConfig": "kinematic_loop", "TrainCheckResult": "train_check",
    "check_train": "train_check",
    "BodyFootprint": "world", "Train": "world", "World": "world", "draw_poses": "world",
    "save_diagnostic": "world",
}
"""The submodule of each name of the API (None: the name is a submodule). A name's submodule is
imported when the name is first used (PEP 562), so importing one submodule (``world`` for a
map, say) does not import them all (OMPL, the lattice search)."""


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    module = importlib.import_module(f".{_EXPORTS[name] or name}", __name__)
    value = module if _EXPORTS[name] is None else getattr(module, name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_EXPORTS))


__all__ = [
    "REASONS", "PlanningError", "PlanningInputError", "PlannedPath", "PLANNERS", "PlannerConfig",
    "ReedsSheppCurve", "plan", "primitives_to_segments", "rs_distance",
    "turning_radius_from_joint_limit", "Primitive", "evaluate_primitives", "recover_primitives",
    "TrackerConfig", "TrainCheckResult", "check_train", "BodyFootprint", "Train", "World",
    "draw_poses", "save_diagnostic", "worlds",
]
