"""The ``pushtrain`` command line: plan, co-simulate and look at a robot pushing n trailers.

Exit codes: 0 success; 1 the run completed but the goal was not reached (or the search found
no plan, or a plot could not be drawn); 2 bad input (scenario file, option, path file, output
folder, a start or goal in collision, a goal no way of the train's width reaches).

One module per command in :mod:`pushtrain.cli.commands`; the heavy libraries (OMPL, Dask,
matplotlib) are imported only by the commands that need them.
"""

from __future__ import annotations

import sys

import click

from .commands.analyze import analyze_cmd
from .commands.atlas import atlas_cmd
from .commands.build_fmu import build_fmu_cmd
from .commands.export_bag import export_bag_cmd
from .commands.export_ssp import export_ssp_cmd
from .commands.plan import plan_cmd
from .commands.plan_and_run import plan_and_run
from .commands.run import run_cmd
from .commands.slip_study import slip_study_cmd
from .commands.validate import validate_cmd
from .commands.view import view_cmd
from .logs import to_stderr
from .sweep import sweep_cmd

__all__ = ["cli", "plan_and_run_main"]


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="pushtrain", prog_name="pushtrain",
                      message="%(prog)s %(version)s")
@click.option("-v", "--verbose", count=True, help="More log output on stderr (-v info, -vv debug).")
@click.pass_context
def cli(ctx: click.Context, verbose: int):
    """pushtrain: plan and co-simulate a robot pushing n passive off-hooked trailers.

    \b
    Examples:
      pushtrain plan-and-run examples/l_corridor.toml
      pushtrain validate examples/circle.toml
      pushtrain build-fmu --trailers 3 -o TrailerTrain.fmu
    """
    ctx.with_resource(to_stderr(verbose))


for _command in (plan_and_run, plan_cmd, run_cmd, build_fmu_cmd, analyze_cmd, validate_cmd,
                 slip_study_cmd, export_ssp_cmd, export_bag_cmd, view_cmd, atlas_cmd):
    cli.add_command(_command)
cli.add_command(sweep_cmd)


def plan_and_run_main(standalone_mode: bool = True):
    """``plan-and-run SCENARIO``: the main job on its own (the console script is
    :func:`pushtrain.cli.entry.plan_and_run`)."""
    with to_stderr(0):
        return plan_and_run.main(args=sys.argv[1:], prog_name="plan-and-run",
                                 help_option_names=["-h", "--help"],
                                 standalone_mode=standalone_mode)


def pushtrain_main(standalone_mode: bool = True):
    """``pushtrain COMMAND ...`` (the console script is :func:`pushtrain.cli.entry.pushtrain`)."""
    return cli.main(args=sys.argv[1:], prog_name="pushtrain", standalone_mode=standalone_mode)


if __name__ == "__main__":  # pragma: no cover
    cli()
