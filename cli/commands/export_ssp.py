"""``pushtrain export-ssp``: the closed loop as an SSP 1.0 package for any FMI tool."""

from __future__ import annotations

from pathlib import Path

import click

from ..common import (
    BadInput,
    check_map,
    click_errors,
    load_scenario_with_overrides,
    scenario_argument,
    trailers_option,
)
from ..runs import describe_path, plan_or_fail
from .run import load_path_file

__all__ = ["export_ssp_cmd"]


def _check_target(out: str) -> Path:
    """``out`` as a Path, or BadInput: an empty name, a folder, a missing folder, or anything
    there that is not an earlier SSP package (a file of another kind, a link, a device)."""
    from pushtrain.mission.ssp import SSP_TARGETS, ssp_target_problem

    if not out.strip():
        raise BadInput(f"-o {out!r}: an empty file name; allowed: a file path such as "
                       "mission.ssp in an existing, writable folder")
    target = Path(out)
    folder = target.parent if str(target.parent) else Path(".")
    if target.is_dir():
        raise BadInput(f"-o {out}: is a folder; allowed: a file path such as mission.ssp in an "
                       "existing, writable folder")
    if not folder.is_dir():
        raise BadInput(f"-o {out}: the folder {folder} does not exist; allowed: a file path in "
                       "an existing, writable folder")
    problem = ssp_target_problem(target)
    if problem is not None:
        raise BadInput(f"-o {out}: {problem}; allowed: {SSP_TARGETS}")
    return target


@click.command("export-ssp")
@scenario_argument
@click.option("--out", "-o", "out", required=True, type=click.Path(dir_okay=False),
              metavar="MISSION.ssp",
              help="The SSP package to write: a new path, or an earlier package (replaced "
                   "atomically); nothing else is replaced.")
@click.option("--path", "path_file", type=click.Path(exists=True, dir_okay=False),
              metavar="PATH.json",
              help="A saved path (from `plan --out`) instead of planning or the scripted "
                   "reference.")
@click.option("--ospconfig", is_flag=True,
              help="Also put libcosim's OspSystemStructure.xml into the package.")
@trailers_option
@click.option("--seed", type=click.IntRange(min=1), metavar="S", help="Override the scenario seed.")
def export_ssp_cmd(scenario, out, path_file, ospconfig, trailers, seed):
    """Export the mission's closed loop as an SSP 1.0 package: the plant FMU (TrailerTrain),
    the controller FMU (BackwardController, pushtrain's control law with the mission's
    reference in its resources), every connection, the parameters and the default experiment.

    \b
    A 'plan' mission is planned first (or give --path); a 'scripted' one takes its reference.
    Examples:
      pushtrain export-ssp examples/l_corridor.toml -o l_corridor.ssp
      pushtrain export-ssp examples/bay.toml --path bay_path.json -o bay.ssp --ospconfig
    Run it with libcosim: CosimExecution.from_ssp_file("l_corridor.ssp") (see the README).
    """
    from pushtrain.mission.runner import scripted_reference
    from pushtrain.mission.ssp import export_ssp

    sc = load_scenario_with_overrides(scenario, trailers, seed)
    target = _check_target(out)
    if path_file:
        path = load_path_file(path_file)
        reference = path.to_reference(speed=sc.planner.speed, cusp_dwell=sc.planner.cusp_dwell)
    elif sc.mission.kind == "scripted":
        reference = scripted_reference(sc)
    elif sc.mission.kind == "plan":
        check_map(sc)
        with click_errors():
            path = plan_or_fail(sc, None)
        click.echo(describe_path(path))
        reference = path.to_reference(speed=sc.planner.speed, cusp_dwell=sc.planner.cusp_dwell)
    else:
        raise BadInput(f"{scenario}: mission.kind = {sc.mission.kind!r} has no plan and no "
                       "scripted reference to export: give --path PATH.json, or a 'plan' or "
                       "'scripted' mission")
    with click_errors():
        try:
            done = export_ssp(sc, reference, target, ospconfig=ospconfig)
        except OSError as exc:
            raise BadInput(f"-o {out}: cannot be written: {exc.strerror or exc}; allowed: a "
                           "file path in an existing, writable folder") from None
    for warning in done.warnings:
        click.echo(f"not exported: {warning}", err=True)
    click.echo(f"ssp: {done.path} (step {done.step:g} s, stop time {done.stop_time:.3f} s, "
               f"{len(done.connections)} connections)")
