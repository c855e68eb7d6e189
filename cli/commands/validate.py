"""``pushtrain validate``: check a scenario file."""

from __future__ import annotations

import click

from ..common import check_map, load_scenario_with_overrides, scenario_argument

__all__ = ["validate_cmd"]


@click.command("validate")
@scenario_argument
def validate_cmd(scenario):
    """Check a scenario file: every bad field is reported with its path; exit 2 if any.

    \b
    Example:
      pushtrain validate examples/l_corridor.toml
    """
    sc = load_scenario_with_overrides(scenario)
    check_map(sc)
    click.echo(f"{scenario}: ok ({sc.mission.kind} mission, n = {sc.train.n} trailers)")
