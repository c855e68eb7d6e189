"""``pushtrain validate``: check a scenario file."""

from __future__ import annotations

import click

from pushtrain.errors import PushtrainError

from ..common import (
    check_map,
    click_error,
    load_scenario_with_overrides,
    scenario_argument,
)

__all__ = ["validate_cmd"]


@click.command("validate")
@scenario_argument
def validate_cmd(scenario):
    """Check a scenario file: every bad field is reported with its path; exit 2 if any. A
    plan mission's start and goal are checked as the planner checks them before it searches
    (their clearances, a goal no way of the train's width reaches).

    \b
    Example:
      pushtrain validate examples/l_corridor.toml
    """
    sc = load_scenario_with_overrides(scenario)
    check_map(sc)
    if sc.mission.kind == "plan":
        # what plan-and-run refuses before it searches: a start or goal without its clearance,
        # a goal no way of the train's width reaches
        from pushtrain.mission.runner import check_plan

        try:
            check_plan(sc)
        except PushtrainError as exc:  # the scenario's (exit 2), or a build's (a compiler, 1)
            raise click_error(exc) from None
    click.echo(f"{scenario}: ok ({sc.mission.kind} mission, n = {sc.train.n} trailers)")
