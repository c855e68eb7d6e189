"""What ``plan``, ``run`` and ``plan-and-run`` share: planning with a diagnostic picture on
failure, running a scenario into its folder, and the text they print."""

from __future__ import annotations

import contextlib
import json
import logging
import math
import time
from pathlib import Path
from typing import TYPE_CHECKING

import click

from pushtrain.files import atomic_write_text

from .exits import EXIT_NOT_REACHED, EXIT_OK, interruption
from .progress import Phases
from .rundir import STATUS_INTERRUPTED

if TYPE_CHECKING:
    from pushtrain.mission.scenario import Scenario

__all__ = ["plan_or_fail", "write_path", "write_scenario", "describe_path", "summary_text",
           "run_and_report", "PlotFailure"]

log = logging.getLogger(__name__)


def plan_or_fail(sc: Scenario, out_dir: Path | None, phases: Phases | None = None):
    """Plan ``sc``'s path (as phase ``plan`` of ``phases``, if given); on a PlanningError save
    ``planning_failure.png`` and ``report.html`` in ``out_dir`` (if given) and re-raise it."""
    from pushtrain.errors import PlanningError
    from pushtrain.mission.runner import plan_path

    t0 = time.perf_counter()
    try:
        with _phase(phases, "plan", f"planning the path ({sc.planner.planner})",
                    tick_s=PLAN_TICK_S):
            path = plan_path(sc)
    except PlanningError as exc:
        if out_dir is not None:
            _save_partial_path(sc, out_dir, exc)
            _save_diagnostic(sc, out_dir / "planning_failure.png", exc)
            _save_failure_page(sc, out_dir / "report.html", exc)
        raise
    log.info("planned %d segments, %.2f m, %d cusps in %.2f s with the map's preparation and "
             "the planner's imports (the search itself %.2f s)", len(path.segments),
             path.length, path.n_cusps, time.perf_counter() - t0,
             float(path.info.get("time", math.nan)))
    return path


def _save_partial_path(sc: Scenario, out_dir: Path, exc) -> None:
    """``partial_path.json`` of a failed plan: the closest the search came (a planned-path
    document with ``info.partial`` true), when the planner says; ``export-bag`` shows it."""
    from pushtrain.core.segment import Segment
    from pushtrain.planner.path import PlannedPath
    from pushtrain.ros.run_folder import PARTIAL_PATH_JSON

    closest = (getattr(exc, "details", None) or {}).get("closest") or {}
    if not closest.get("segments"):
        return
    try:
        segments = [Segment.from_dict(g) for g in closest["segments"]]
        arcs = [abs(g.curvature) for g in segments if g.kind == "arc" and g.curvature]
        path = PlannedPath((sc.start.x, sc.start.y, math.radians(sc.start.theta_deg)), segments,
                           1.0 / max(arcs) if arcs else 0.0,
                           info={"partial": True, "reason": getattr(exc, "reason", None),
                                 "remaining_m": closest.get("remaining")})
        write_path(path, out_dir / PARTIAL_PATH_JSON)
    except Exception as err:  # the partial path must not hide the planning error
        log.warning("could not save the partial path: %s", err)


def _save_diagnostic(sc: Scenario, png: Path, exc=None) -> None:
    from pushtrain.mission.runner import train_of, world_of
    from pushtrain.planner.diagnostic import save_diagnostic

    where = getattr(exc, "where", None)
    marks = [(where[0], where[1], getattr(exc, "reason", ""))] if where else None
    try:
        save_diagnostic(png, world_of(sc),
                        (sc.start.x, sc.start.y, math.radians(sc.start.theta_deg)),
                        (sc.goal.x, sc.goal.y, math.radians(sc.goal.theta_deg)), train_of(sc),
                        title=None if exc is None else _wrapped(str(exc)), marks=marks,
                        failure=getattr(exc, "details", None))
    except Exception as err:  # the diagnosis must not hide the planning error
        log.warning("could not save the diagnostic picture: %s", err)


def _save_failure_page(sc: Scenario, page: Path, exc) -> None:
    """``report.html`` of a failed plan: the search tree, the best partial plan, the route and
    its bottleneck (:func:`pushtrain.report.html.plot_failure_report`)."""
    from pushtrain.mission.runner import world_of
    from pushtrain.report.html import plot_failure_report

    from .plotting import footprints_of, keep_out_of

    try:
        plot_failure_report(
            sc.train.n, getattr(exc, "details", None) or {}, page, world=world_of(sc),
            footprints=footprints_of(sc),
            start=(sc.start.x, sc.start.y, math.radians(sc.start.theta_deg)),
            goal=(sc.goal.x, sc.goal.y, math.radians(sc.goal.theta_deg)),
            message=str(exc), reason=getattr(exc, "reason", None),
            keep_out=keep_out_of(sc))
    except Exception as err:  # the page must not hide the planning error
        log.warning("could not save the failure page: %s", err)


def write_path(path, target: Path) -> None:
    """Write a planned path as JSON (atomically)."""
    atomic_write_text(target, path.to_json() + "\n")


def write_scenario(sc: Scenario, out_dir: Path) -> None:
    """Write the resolved scenario (every default filled in) as ``scenario.json``."""
    atomic_write_text(out_dir / "scenario.json", sc.model_dump_json(indent=2))


def describe_path(path) -> str:
    """A few lines describing a planned path: length, cusps, one line per segment."""
    lines = [f"path: {path.length:.2f} m, {len(path.segments)} segments, {path.n_cusps} cusp(s), "
             f"turning radius {path.turning_radius:.2f} m"]
    for seg in path.segments:
        if seg.kind == "line":
            kind = "line"
        else:
            side = "left" if seg.curvature > 0 else "right"
            kind = f"arc r={1 / abs(seg.curvature):.2f} m {side}"
        lines.append(f"  {'push' if seg.direction > 0 else 'pull'} {kind:<22} {seg.length:6.2f} m")
    return "\n".join(lines)


def summary_text(summary: dict) -> str:
    """The one-screen summary of a run: status, tracking errors, joint angles, forces, slip."""
    lines = [f"status: {summary['status']} - {summary['message']}"]
    if "lateral_error_m" in summary and summary.get("mission") != "rotation":
        lat, head = summary["lateral_error_m"], summary["heading_error_rad"]
        lines.append(f"lateral error of the last trailer: rms {lat['rms'] * 100:.2f} cm, "
                     f"max {lat['max'] * 100:.2f} cm, final {lat['final'] * 100:.2f} cm")
        lines.append(f"heading error: rms {math.degrees(head['rms']):.2f} deg, "
                     f"max {math.degrees(head['max']):.2f} deg")
    if "max_abs_phi_deg" in summary:
        lines.append("max |joint angle| [deg]: "
                     + ", ".join(f"{a:.1f}" for a in summary["max_abs_phi_deg"]))
        ratios = summary["max_F_lat_ratio"]
        lines.append("max |F_lat| / friction limit: " + ", ".join(
            f"{r:.2f}" if r is not None else "-" for r in ratios))
        slips = [s for s in summary["slip"] if s["events"]]
        lines.append("slip: " + (", ".join(f"trailer {s['trailer']} from t = {s['first_t']:.2f} s"
                                           for s in slips) if slips else "none"))
    lines.append(f"{summary.get('steps', 0)} steps in {summary.get('wall_time_s', 0):.2f} s")
    return "\n".join(lines)


PLAN_TICK_S = 10.0
"""Seconds between the lines that say planning is still going (a long plan is not silent)."""


def _phase(phases: Phases | None, name: str, what: str, tick_s: float | None = None):
    return (phases.phase(name, what, tick_s) if phases is not None
            else contextlib.nullcontext())


def _build_fmu_once(sc: Scenario, phases: Phases | None) -> None:
    """The scenario's FMU compiled as a phase of its own on first use (a few seconds; cached
    for every later run) or when the cached copy is damaged, so that the co-simulation's time
    is the co-simulation's."""
    from pushtrain.fmu.build import build_fmu, cache_damage, cached_path, is_built
    from pushtrain.mission.runner import fmu_build_args

    args = fmu_build_args(sc)
    if not is_built(**args):
        version = args["fmi_version"]
        what = (f"rebuilding the FMU (FMI {version}.0; the cached copy is damaged)"
                if cache_damage(cached_path(**args)) else
                f"building the FMU (FMI {version}.0; first use, cached for later runs)")
        with _phase(phases, "build FMU", what):
            build_fmu(**args)


def _summary_on_interrupt(result, out_dir: Path):
    """An exit callback: on Ctrl-C or SIGTERM once the run is co-simulated, ``summary.json``
    says ``interrupted`` (its exit code, 130 or 143), with the run's numbers and its own end as
    ``run_status`` and ``run_message``. It must not say ``goal_reached`` while the pictures (or
    the results) are missing."""

    def on_exit(kind, exc, trace) -> bool:
        if kind is not None and issubclass(kind, KeyboardInterrupt):
            code, what = interruption(exc)
            summary = {"status": STATUS_INTERRUPTED,
                       "message": f"{what}: the files written so far are kept",
                       "exit_code": code, "run_status": result.status,
                       "run_message": result.message}
            summary.update((k, v) for k, v in result.summary.items() if k not in summary)
            try:
                atomic_write_text(out_dir / "summary.json", json.dumps(summary, indent=2))
            except OSError as err:  # must not hide the interruption
                log.warning("could not write %s: %s", out_dir / "summary.json", err)
        return False

    return on_exit


class PlotFailure(click.ClickException):
    """Some pictures could not be drawn (exit 1); the results are saved."""

    exit_code = EXIT_NOT_REACHED


def run_and_report(sc: Scenario, out_dir: Path, reference, path, files=(), *,
                   csv: bool = False, phases: Phases | None = None, plotter=None) -> int:
    """Co-simulate ``sc``, save the results into ``out_dir`` (``results.csv`` too with
    ``csv``), draw the picture ``files`` (from :func:`pushtrain.cli.plotting.chosen_files`),
    print the summary; the exit code (0 if the goal was reached or the fixed-horizon run
    completed, else 1). Each step is a phase of ``phases``, if given.

    ``report.html`` is written here, from the data (no matplotlib). ``plotter`` (from
    :func:`pushtrain.cli.plotting.plotter`, started before planning) draws the matplotlib
    files (PNGs, GIF) while the results are saved and the page written; without one they are
    drawn here, after saving. A picture that cannot be drawn raises :class:`PlotFailure`
    (exit 1) once the summary is printed; the results and the other pictures stay written.
    """
    from pushtrain.mission.runner import run_scenario
    from pushtrain.report import HTML_FILE

    from .pictures import draw_page
    from .plotting import plotter as start_plotter

    files = tuple(files)
    drawn = tuple(name for name in files if name != HTML_FILE)  # by matplotlib
    with contextlib.ExitStack() as stack:
        if drawn and plotter is None:
            plotter = stack.enter_context(start_plotter(sc, drawn, processes=0))
        _build_fmu_once(sc, phases)
        with _phase(phases, "co-simulate", "co-simulating"):
            result = run_scenario(sc, None, reference=reference)
        stack.push(_summary_on_interrupt(result, out_dir))
        if drawn:
            plotter.submit(out_dir, result, path)
        with _phase(phases, "save", "saving the results"):
            result.save(out_dir, csv=csv)
        problems = []
        if HTML_FILE in files:
            with _phase(phases, "page", f"writing {HTML_FILE}"):
                problem = draw_page(sc, out_dir, result, path)
            problems += [problem] if problem is not None else []
        if drawn:  # one phase: the plot processes draw the GIF beside the plots
            what = f"plotting {', '.join(drawn)}"
            with _phase(phases, "plots", what):
                problems += plotter.wait(drawn)
            plotter.close()  # the plot processes end (and log their peak memory in run.log)
    if phases is not None:
        phases.done()
    click.echo(summary_text(result.summary))
    click.echo(f"results: {out_dir}")
    if problems:
        reasons: dict[str, list[str]] = {}  # the files that failed for each reason, in order
        for problem in problems:
            reasons.setdefault(problem.message, []).append(problem.name)
        raise PlotFailure("could not draw " + "; ".join(
            f"{', '.join(names)}: {why}" for why, names in reasons.items())
            + f" (the results and the other files are in {out_dir}; details in run.log)")
    return EXIT_OK if result.ok else EXIT_NOT_REACHED


def _wrapped(text: str, width: int = 110, lines: int = 6) -> str:
    """``text`` in lines of at most ``width`` characters (at most ``lines`` of them)."""
    import textwrap

    out = textwrap.wrap(text, width)
    return "\n".join(out[:lines] + (["..."] if len(out) > lines else []))
