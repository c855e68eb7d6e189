"""``pushtrain plan-and-run``: the main job."""

from __future__ import annotations

import sys

import click

from ..common import (
    check_map,
    csv_option,
    load_scenario_with_overrides,
    out_dir_option,
    plot_processes_option,
    scenario_argument,
    trailers_option,
)
from ..pictures import chosen_files, pictures_options
from ..plotting import plotter
from ..progress import Phases
from ..rundir import run_folder
from ..runs import describe_path, plan_or_fail, run_and_report, write_path, write_scenario
from .export_bag import bag_after_run

__all__ = ["plan_and_run"]


@click.command("plan-and-run")
@scenario_argument
@out_dir_option
@trailers_option
@click.option("--seed", type=click.IntRange(min=1), metavar="S", help="Override the scenario seed.")
@pictures_options
@csv_option
@plot_processes_option
@click.option("--bag", is_flag=True,
              help="Also write the run as a rosbag2 folder OUT/bag (see export-bag).")
def plan_and_run(scenario, out, trailers, seed, plots, gif, no_plots, no_gif, csv,
                 plot_processes, bag):
    """Plan the last trailer's path, co-simulate the FMU with the controller, plot the run.

    \b
    Example:
      pushtrain plan-and-run examples/l_corridor.toml --out runs/l
    Writes scenario.json, path.json, results.npz (results.csv with --csv), summary.json,
    run.log and report.html (--plots all: the PNGs too; --gif: train.gif; --bag: the
    rosbag2 folder bag/). Progress goes to stderr, one line per phase.
    """
    files = chosen_files(plots, gif, no_plots, no_gif)
    phases = Phases()
    sc = load_scenario_with_overrides(scenario, trailers, seed)
    # the plot processes get ready (import matplotlib) while the map is checked, the path
    # planned and the run made
    with plotter(sc, files, processes=plot_processes) as pictures:
        check_map(sc)
        with bag_after_run(bag) as bag_of, run_folder(out, sc.name, sc) as out_dir:
            bag_of.folder = out_dir
            write_scenario(sc, out_dir)
            reference = path = None
            if sc.mission.kind == "plan":
                path = plan_or_fail(sc, out_dir, phases)
                write_path(path, out_dir / "path.json")
                click.echo(describe_path(path))
                reference = path.to_reference(speed=sc.planner.speed,
                                              cusp_dwell=sc.planner.cusp_dwell)
            code = run_and_report(sc, out_dir, reference, path, files, csv=csv,
                                  phases=phases, plotter=pictures)
    sys.exit(code)
