"""``pushtrain run``: co-simulate a saved path or a scripted reference."""

from __future__ import annotations

import sys

import click

from ..common import (
    BadInput,
    check_map,
    csv_option,
    load_scenario_with_overrides,
    out_dir_option,
    plot_processes_option,
    scenario_argument,
)
from ..pictures import chosen_files, pictures_options
from ..plotting import plotter
from ..progress import Phases
from ..rundir import run_folder
from ..runs import run_and_report, write_path, write_scenario

__all__ = ["run_cmd", "load_path_file"]


def load_path_file(path_file: str):
    from pushtrain.planner.path import PlannedPath

    try:
        return PlannedPath.from_json(path_file)
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise BadInput(f"--path {path_file}: not a usable path file (from `pushtrain plan "
                       f"--out`): {exc}") from None
    except OSError as exc:
        raise BadInput(f"--path {path_file}: cannot be read: {exc.strerror}") from None


def _check_path_fits(sc, path, path_file) -> None:
    """Refuse a saved path that does not start at the scenario's start or end at its goal
    (the run would follow it anyway, and the scenario's files would describe another run)."""
    import math

    tol_pos = max(0.01, sc.sim.goal_tolerance)
    tol_head = max(math.radians(1.0), math.radians(sc.sim.goal_heading_tolerance_deg))
    for name, pose, where in (("start", sc.start, path.start), ("goal", sc.goal, path.goal)):
        if pose is None:
            continue
        want = (pose.x, pose.y, math.radians(pose.theta_deg))
        off = math.hypot(where[0] - want[0], where[1] - want[1])
        turn = abs(math.remainder(float(where[2]) - want[2], 2.0 * math.pi))
        if off > tol_pos or turn > tol_head:
            raise BadInput(
                f"--path {path_file}: the path's {'end' if name == 'goal' else 'start'} "
                f"({where[0]:.3f}, {where[1]:.3f}, {math.degrees(where[2]):.1f} deg) is not the "
                f"scenario's {name} ({want[0]:.3f}, {want[1]:.3f}, {pose.theta_deg:.1f} deg): "
                f"it must be within {tol_pos:g} m and {math.degrees(tol_head):g} deg (a path "
                "planned for this scenario: `pushtrain plan SCENARIO --out DIR`)")


@click.command("run")
@scenario_argument
@click.option("--path", "path_file", type=click.Path(exists=True, dir_okay=False),
              metavar="PATH.json",
              help="A saved path (from `plan --out`); default: the scenario's scripted reference.")
@out_dir_option
@pictures_options
@csv_option
@plot_processes_option
def run_cmd(scenario, path_file, out, plots, gif, no_plots, no_gif,
            csv, plot_processes):
    """Co-simulate a saved path or the scenario's scripted line/arc reference.

    \b
    Examples:
      pushtrain run examples/circle.toml
      pushtrain run examples/bay.toml --path bay_path.json
    Writes scenario.json, path.json (with --path), results.npz (results.csv with --csv),
    summary.json, run.log and report.html (--plots all: the PNGs too; --gif: train.gif).
    Progress goes to stderr, one line per phase.
    """
    files = chosen_files(plots, gif, no_plots, no_gif)
    phases = Phases()
    sc = load_scenario_with_overrides(scenario)
    # the plot processes get ready (import matplotlib) while the map is checked and the run
    # made
    with plotter(sc, files, processes=plot_processes) as pictures:
        check_map(sc)
        path = None
        if path_file:
            path = load_path_file(path_file)
            _check_path_fits(sc, path, path_file)
        elif sc.mission.kind == "plan":
            raise BadInput(f"{scenario}: mission.kind = 'plan' has no scripted reference: give "
                           "--path PATH.json or use plan-and-run")
        with run_folder(out, sc.name, sc) as out_dir:
            write_scenario(sc, out_dir)
            reference = None
            if path is not None:
                write_path(path, out_dir / "path.json")
                reference = path.to_reference(speed=sc.planner.speed,
                                              cusp_dwell=sc.planner.cusp_dwell)
            code = run_and_report(sc, out_dir, reference, path, files, csv=csv,
                                  phases=phases, plotter=pictures)
    sys.exit(code)
