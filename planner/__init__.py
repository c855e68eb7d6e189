"""Planner: the whole train's motion under its controller (default ``planner = "lattice"``,
:mod:`~pushtrain.planner.lattice`), the OMPL Reeds-Shepp planners of the last trailer, the
whole-train check and the reference export.

Public API, each name imported from the module where it lives::

    pushtrain.planner.planner.plan(world, start, goal, train, config, start_headings) -> PlannedPath
    pushtrain.planner.config.PlannerConfig, PLANNERS, turning_radius_from_joint_limit
    pushtrain.planner.config.TrackerConfig  (the closed loop the planner predicts: controller,
        speed, dwell, step, settle time; run on pushtrain.core.engine)
    pushtrain.planner.path.PlannedPath.to_reference(speed, cusp_dwell) / to_json / from_json
    pushtrain.planner.train_check.check_train(world, train, start, segments, ...)
        -> TrainCheckResult  (its ``run``: the engine's EngineRun)
    pushtrain.planner.train.Train.uniform(n), BodyFootprint(length, width, offset)
    pushtrain.planner.diagnostic.save_diagnostic(path, world, start, goal, train, ...)
    pushtrain.facility.free_space.World.from_dict(d)  (the map: :mod:`pushtrain.facility`)
    pushtrain.errors.PlanningError(reason, message, where)

Importing this package imports none of its modules (no OMPL, no lattice search).
"""

__all__: list[str] = []
