"""Missions: a scenario file validated into a :class:`~.scenario.Scenario`, and the runner that
turns it into a world, a train, a plan and a co-simulation (:mod:`.runner`).

Stands on the planner, the co-simulation and the core; the CLI and the studies use it.
"""

__all__: list[str] = []
