"""The ``pushtrain`` command line: plan, co-simulate and look at a robot pushing n trailers.

Exit codes: 0 success; 1 the run completed but the goal was not reached (or no plan was found);
2 bad input (scenario file, option, path file).
"""

from __future__ import annotations

import logging
import math
import sys
import time
from pathlib import Path

import click

from pushtrain.mission.scenario import Scenario, ScenarioError, load_scenario

from .common import (_INPUT_REASONS, EXIT_BAD_INPUT, EXIT_NOT_REACHED, EXIT_OK, BadInput,  # noqa: F401
                     _scenario, log)


def _out_dir(out: str | None, sc: Scenario) -> Path:
    if out:
        path = Path(out)
    else:
        path = Path("runs") / f"{sc.name}-{time.strftime('%Y%m%d-%H%M%S')}"
    path.mkdir(parents=True, exist_ok=True)
    return path


def _attach_log(out_dir: Path) -> logging.Handler:
    handler = logging.FileHandler(out_dir / "run.log", mode="a")
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    handler.setLevel(logging.DEBUG)
    root = logging.getLogger("pushtrain")
    root.setLevel(logging.DEBUG)
    root.addHandler(handler)
    return handler


def _plan(sc: Scenario, out_dir: Path | None):
    """Plan; on failure save a diagnostic picture and raise the right click exception."""
    from pushtrain.planner import PlanningError

    from pushtrain.mission.runner import plan_path, train_of, world_of

    t0 = time.perf_counter()
    try:
        path = plan_path(sc)
    except PlanningError as exc:
        if out_dir is not None:
            try:
                from pushtrain.planner.world import save_diagnostic

                save_diagnostic(out_dir / "planning_failure.png", world_of(sc),
                                (sc.start.x, sc.start.y, math.radians(sc.start.theta_deg)),
                                (sc.goal.x, sc.goal.y, math.radians(sc.goal.theta_deg)),
                                train_of(sc))
            except Exception as diag_exc:  # the diagnosis must not hide the planning error
                log.warning("could not save the diagnostic picture: %s", diag_exc)
        reason = getattr(exc, "reason", "")
        cls = BadInput if reason in _INPUT_REASONS or isinstance(exc, ValueError) else click.ClickException
        err = cls(f"planning failed ({reason}): {exc}")
        if cls is click.ClickException:
            err.exit_code = EXIT_NOT_REACHED
        raise err from None
    log.info("planned %d segments, %.2f m, %d cusps in %.2f s", len(path.segments), path.length,
             path.n_cusps, time.perf_counter() - t0)
    return path


def _describe_path(path) -> str:
    lines = [f"path: {path.length:.2f} m, {len(path.segments)} segments, {path.n_cusps} cusp(s), "
             f"turning radius {path.turning_radius:.2f} m"]
    for seg in path.segments:
        kind = "line" if seg.kind == "line" else f"arc r={1 / abs(seg.curvature):.2f} m {'left' if seg.curvature > 0 else 'right'}"
        lines.append(f"  {'push' if seg.direction > 0 else 'pull'} {kind:<22} {seg.length:6.2f} m")
    return "\n".join(lines)


def _summary_text(summary: dict) -> str:
    lines = [f"status: {summary['status']} - {summary['message']}"]
    if "lateral_error_m" in summary and summary.get("mission") != "rotation":
        lat, head = summary["lateral_error_m"], summary["heading_error_rad"]
        lines.append(f"lateral error of the last trailer: rms {lat['rms'] * 100:.2f} cm, "
                     f"max {lat['max'] * 100:.2f} cm, final {lat['final'] * 100:.2f} cm")
        lines.append(f"heading error: rms {math.degrees(head['rms']):.2f} deg, "
                     f"max {math.degrees(head['max']):.2f} deg")
    if "max_abs_phi_deg" in summary:
        lines.append("max |joint angle| [deg]: " + ", ".join(f"{a:.1f}" for a in summary["max_abs_phi_deg"]))
        ratios = summary["max_F_lat_ratio"]
        lines.append("max |F_lat| / friction limit: " + ", ".join(
            f"{r:.2f}" if r is not None else "-" for r in ratios))
        slips = [s for s in summary["slip"] if s["events"]]
        lines.append("slip: " + (", ".join(f"trailer {s['trailer']} from t = {s['first_t']:.2f} s"
                                           for s in slips) if slips else "none"))
    lines.append(f"{summary.get('steps', 0)} steps in {summary.get('wall_time_s', 0):.2f} s")
    return "\n".join(lines)


def _run_and_report(sc: Scenario, out_dir: Path, reference, path, plots: bool, gif: bool) -> int:
    from pushtrain.mission.runner import run_scenario, world_of

    result = run_scenario(sc, out_dir, reference=reference)
    if plots:
        from pushtrain.report import plots as plotting

        footprints = {"robot": (sc.train.robot_size.length, sc.train.robot_size.width),
                      "trailer": (sc.train.trailer_size.length, sc.train.trailer_size.width)}
        path_xy = None if path is None else path.poses[:, :2]
        try:
            from pushtrain.mission.runner import geometry_of

            written = plotting.plot_all(result, sc.train.n, out_dir, world=world_of(sc),
                                        path_xy=path_xy, footprints=footprints, gif=gif,
                                        geometry=geometry_of(sc))
            log.info("plots: %s", ", ".join(p.name for p in written))
        except Exception as exc:  # plots must never lose the results already written
            log.exception("plotting failed")
            click.echo(f"warning: plotting failed ({exc}); results are in {out_dir}", err=True)
    click.echo(_summary_text(result.summary))
    click.echo(f"results: {out_dir}")
    return EXIT_OK if result.ok else EXIT_NOT_REACHED


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.option("-v", "--verbose", count=True, help="More log output on stderr (-v info, -vv debug).")
def cli(verbose: int):
    """pushtrain: plan and co-simulate a robot pushing n passive off-hooked trailers.

    \b
    Examples:
      pushtrain plan-and-run examples/l_corridor.toml
      pushtrain validate examples/circle.toml
      pushtrain build-fmu --trailers 3 -o TrailerTrain.fmu
    """
    _log_to_stderr(verbose)


def _log_to_stderr(verbose: int) -> None:
    """Log pushtrain's messages on stderr (warnings; -v info, -vv debug)."""
    level = logging.WARNING if verbose == 0 else logging.INFO if verbose == 1 else logging.DEBUG
    handler = logging.StreamHandler(sys.stderr)
    handler.setLevel(level)
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    logging.getLogger("pushtrain").addHandler(handler)


_scenario_arg = click.argument("scenario", type=click.Path(exists=True, dir_okay=False))
_out_opt = click.option("--out", "-o", "out", type=click.Path(file_okay=False), metavar="DIR",
                        help="Output folder (default runs/<scenario>-<timestamp>/).")


@cli.command("plan-and-run")
@_scenario_arg
@_out_opt
@click.option("--trailers", type=click.IntRange(1, 50), metavar="N", help="Override train.n.")
@click.option("--seed", type=click.IntRange(min=1), metavar="S", help="Override the scenario seed.")
@click.option("--no-plots", is_flag=True, help="Skip the PNG plots and the GIF.")
@click.option("--no-gif", is_flag=True, help="Skip the animated GIF (plots only).")
def plan_and_run(scenario, out, trailers, seed, no_plots, no_gif):
    """Plan the last trailer's path, co-simulate the FMU with the controller, plot the run.

    \b
    Example:
      pushtrain plan-and-run examples/l_corridor.toml --out runs/l
    Writes scenario.json, path.json, results.csv/.npz, summary.json, run.log and plots.
    """
    sc = _scenario(scenario, trailers, seed)
    _check_map(sc)
    out_dir = _out_dir(out, sc)
    handler = _attach_log(out_dir)
    try:
        from pushtrain.files import atomic_write_text

        atomic_write_text(out_dir / "scenario.json", sc.model_dump_json(indent=2))
        reference, path = None, None
        if sc.mission.kind == "plan":
            path = _plan(sc, out_dir)
            path.to_json(out_dir / "path.json")
            click.echo(_describe_path(path))
            reference = path.to_reference(speed=sc.planner.speed, cusp_dwell=sc.planner.cusp_dwell)
        code = _run_and_report(sc, out_dir, reference, path, not no_plots, not no_gif)
    finally:
        logging.getLogger("pushtrain").removeHandler(handler)
        handler.close()
    sys.exit(code)


def _check_map(sc: Scenario) -> None:
    from pushtrain.mission.runner import check_start_in_map

    try:
        check_start_in_map(sc)
    except ScenarioError as exc:
        raise BadInput(str(exc)) from None
    except ValueError as exc:  # the planner's input errors (bad polygons)
        raise BadInput(f"{sc.name}: map: {exc}") from None


@cli.command("plan")
@_scenario_arg
@click.option("--out", "-o", "out", type=click.Path(dir_okay=False), metavar="FILE",
              help="Write the path as JSON (default: print a description only).")
@click.option("--seed", type=click.IntRange(min=1), metavar="S", help="Override the scenario seed.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), metavar="PNG",
              help="Draw the map and the planned path.")
def plan_cmd(scenario, out, seed, plot_path):
    """Plan the last trailer's path only (no co-simulation).

    \b
    Example:
      pushtrain plan examples/bay.toml --out bay_path.json --plot bay_path.png
    """
    sc = _scenario(scenario, seed=seed)
    if sc.mission.kind != "plan":
        raise BadInput(f"{scenario}: mission.kind = {sc.mission.kind!r}: 'plan' needs mission.kind = 'plan'")
    _check_map(sc)
    path = _plan(sc, None)
    click.echo(_describe_path(path))
    if out:
        path.to_json(out)
        click.echo(f"path: {out}")
    if plot_path:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from pushtrain.mission.runner import world_of

        fig, ax = plt.subplots(figsize=(8, 6))
        world_of(sc).plot(ax)
        ax.plot(path.poses[:, 0], path.poses[:, 1], "-", color="tab:blue", label="planned path (last trailer)")
        ax.plot(*path.poses[0, :2], "go", label="start")
        ax.plot(*path.poses[-1, :2], "r*", markersize=12, label="goal")
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.legend(loc="best")
        ax.set_title(f"{sc.name}: {path.length:.2f} m, {path.n_cusps} cusp(s)")
        fig.tight_layout()
        fig.savefig(plot_path, dpi=120)
        plt.close(fig)
        click.echo(f"plot: {plot_path}")


@cli.command("run")
@_scenario_arg
@click.option("--path", "path_file", type=click.Path(exists=True, dir_okay=False), metavar="PATH.json",
              help="A saved path (from `plan --out`); default: the scenario's scripted reference.")
@_out_opt
@click.option("--no-plots", is_flag=True, help="Skip the PNG plots and the GIF.")
@click.option("--no-gif", is_flag=True, help="Skip the animated GIF (plots only).")
def run_cmd(scenario, path_file, out, no_plots, no_gif):
    """Co-simulate a saved path or the scenario's scripted line/arc reference.

    \b
    Examples:
      pushtrain run examples/circle.toml
      pushtrain run examples/bay.toml --path bay_path.json
    """
    sc = _scenario(scenario)
    path = reference = None
    if path_file:
        from pushtrain.planner.path import PlannedPath

        try:
            path = PlannedPath.from_json(path_file)
        except (ValueError, KeyError, TypeError) as exc:
            raise BadInput(f"{path_file}: not a usable path file: {exc}") from None
        reference = path.to_reference(speed=sc.planner.speed, cusp_dwell=sc.planner.cusp_dwell)
    elif sc.mission.kind == "plan":
        raise BadInput(f"{scenario}: mission.kind = 'plan' has no scripted reference: give "
                       "--path PATH.json or use plan-and-run")
    out_dir = _out_dir(out, sc)
    handler = _attach_log(out_dir)
    try:
        from pushtrain.files import atomic_write_text

        atomic_write_text(out_dir / "scenario.json", sc.model_dump_json(indent=2))
        code = _run_and_report(sc, out_dir, reference, path, not no_plots, not no_gif)
    finally:
        logging.getLogger("pushtrain").removeHandler(handler)
        handler.close()
    sys.exit(code)


@cli.command("build-fmu")
@click.option("--trailers", "-n", type=click.IntRange(1, 50), required=True, metavar="N",
              help="Number of trailers (1 to 50).")
@click.option("--out", "-o", "out", type=click.Path(dir_okay=False), default="TrailerTrain.fmu",
              show_default=True, metavar="FILE", help="Where to write the .fmu.")
@click.option("--force", is_flag=True, help="Rebuild even if cached.")
def build_fmu_cmd(trailers, out, force):
    """Build the TrailerTrain FMI 2.0 co-simulation FMU for N trailers.

    \b
    Example:
      pushtrain build-fmu --trailers 3 -o TrailerTrain.fmu
    """
    from pushtrain.fmu import FmuBuildError, build_fmu

    try:
        path = build_fmu(trailers, out, force=force)
    except FmuBuildError as exc:
        raise click.ClickException(str(exc)) from None
    click.echo(f"{path} (n = {trailers})")


@cli.command("analyze", short_help="Stability (Eq. 12-13, Routh-Hurwitz) and predicted joint-bias offsets.")
@_scenario_arg
def analyze_cmd(scenario):
    """Stability (Eq. 12-13, Routh-Hurwitz) and predicted offsets from joint biases (Eq. 9).

    \b
    Example:
      pushtrain analyze examples/joint_bias_5deg.toml
    """
    from pushtrain.core import analysis

    from pushtrain.mission.runner import bias_model

    sc = _scenario(scenario)
    c = sc.controller
    link, speed, bias, eps = bias_model(sc)
    click.echo(f"controller gains: K_x = {c.k_x}, K_y = {c.k_y}, K_theta = {c.k_theta}; D = {link} m")
    for v_d, label in ((speed, "pushing, direction-of-travel frame"), (-speed, "chain frame (v_d < 0)")):
        poles = analysis.closed_loop_poles(c.k_x, c.k_y, c.k_theta, v_d)
        verdict = analysis.routh_hurwitz(analysis.characteristic_polynomial(c.k_x, c.k_y, c.k_theta, v_d))
        roots = ", ".join(f"{r.real:+.4f}{r.imag:+.4f}j" for r in poles)
        click.echo(f"v_d = {v_d:+.3f} m/s ({label}): Eq. 13 roots {roots} -> "
                   f"{'stable' if verdict.stable else 'UNSTABLE'} (Routh-Hurwitz, "
                   f"{verdict.sign_changes} sign change(s))")
    click.echo(f"effective joint bias: {math.degrees(eps):.3f} deg (alternating sum of "
               f"{[round(math.degrees(b), 3) for b in bias]} deg)")
    exact = analysis.steady_lateral_error(eps, link, c.k_y)
    paper = analysis.steady_lateral_error(eps, link, c.k_y, form="paper")
    if sc.sensors.localize == "last_trailer":
        click.echo(f"predicted steady lateral error y_e (last trailer localized): {exact * 100:.2f} cm "
                   f"(paper's Eq. 9, tan form: {paper * 100:.2f} cm)")
    else:
        est = analysis.steady_lateral_error_estimated_pose(bias, link, c.k_x, c.k_y, c.k_theta, speed)
        click.echo(f"predicted steady lateral error y_e (last trailer computed from the biased joints): "
                   f"{est * 100:.2f} cm; with the last trailer localized it would be "
                   f"{exact * 100:.2f} cm (Eq. 9: {paper * 100:.2f} cm)")


@cli.command("validate")
@_scenario_arg
def validate_cmd(scenario):
    """Check a scenario file: every bad field is reported with its path; exit 2 if any.

    \b
    Example:
      pushtrain validate examples/l_corridor.toml
    """
    sc = _scenario(scenario)
    _check_map(sc)
    click.echo(f"{scenario}: ok ({sc.mission.kind} mission, n = {sc.train.n} trailers)")


def _int_list(text: str) -> tuple[int, ...]:
    out = []
    for part in text.split(","):
        if "-" in part:
            lo, hi = part.split("-", 1)
            out += list(range(int(lo), int(hi) + 1))
        else:
            out.append(int(part))
    return tuple(out)


@cli.command("slip-study")
@click.option("--trailers", default="1-10", show_default=True, metavar="LIST",
              help="Numbers of trailers for the n sweep, e.g. '1-10' or '1,3,7'.")
@click.option("--alphas", default="5,10,15,20,30,40,50", show_default=True, metavar="LIST",
              help="Robot angular accelerations [deg/s^2] for the alpha sweep.")
@click.option("--w-max", "w_max", type=click.FloatRange(min=0, min_open=True), default=10.0,
              show_default=True, metavar="DEG_S", help="Peak yaw rate of the rotation [deg/s].")
@click.option("--payload", type=click.FloatRange(min=0), default=80.0, show_default=True,
              metavar="KG", help="Payload placed on one trailer at a time (payload sweep).")
@_out_opt
def slip_study_cmd(trailers, alphas, w_max, payload, out):
    """Pure-rotation slip study: peak lateral wheel forces against friction (Fig. 16-18).

    Sweeps the number of trailers, the robot's angular acceleration and the payload position
    with the FMU and writes slip_study.csv and slip_study.png.

    \b
    Example:
      pushtrain slip-study --trailers 1-10 --alphas 5,15,30,50 --out runs/slip
    """
    from pushtrain.studies.slipstudy import SlipStudyConfig, plot_slip_study, run_slip_study, write_csv

    try:
        cfg = SlipStudyConfig(trailers=_int_list(trailers),
                              alphas_deg=tuple(float(a) for a in alphas.split(",")),
                              w_max_deg=w_max, payload=payload)
    except ValueError as exc:
        raise BadInput(f"slip-study: {exc}") from None
    out_dir = Path(out) if out else Path("runs") / f"slip-study-{time.strftime('%Y%m%d-%H%M%S')}"
    out_dir.mkdir(parents=True, exist_ok=True)
    with click.progressbar(length=len(cfg.trailers) + len(cfg.alphas_deg) + cfg.n_for_payload,
                           label="slip study", file=sys.stderr) as bar:
        rows = run_slip_study(cfg, progress=lambda done, total: bar.update(1))
    write_csv(rows, out_dir / "slip_study.csv")
    plot_slip_study(rows, out_dir / "slip_study.png")
    for sweep, label in (("trailers", "n"), ("alpha", "alpha [deg/s^2]"), ("payload", "payload on")):
        click.echo(f"{label:>16} | peak |F_lat,1| [N] | limit [N] | slides")
        for r in (r for r in rows if r.sweep == sweep):
            key = r.n if sweep == "trailers" else r.alpha_deg if sweep == "alpha" else r.payload_on
            click.echo(f"{key:>16} | {r.peak[0]:18.2f} | {r.limit[0]:9.2f} | "
                       f"{'yes' if r.peak[0] > r.limit[0] else 'no'}")
    click.echo(f"results: {out_dir}")


def plan_and_run_main():
    """Console script ``plan-and-run SCENARIO``: the main job on its own."""
    _log_to_stderr(0)
    plan_and_run.main(args=sys.argv[1:], prog_name="plan-and-run",
                      help_option_names=["-h", "--help"])


from .sweep import sweep_cmd  # noqa: E402
cli.add_command(sweep_cmd)


if __name__ == "__main__":  # pragma: no cover
    cli()
