"""``pushtrain sweep``: robustness sweeps of a scenario on Dask (or serially).

The scenario layer of :mod:`pushtrain.studies.sweep`: it turns a base :class:`Scenario` and a
:class:`~pushtrain.studies.sweep.SweepSpec` into runs (every resolved scenario validated before
anything runs), plans ``plan`` missions once per distinct train geometry in the client (OMPL
objects are not picklable: the path travels as ``PlannedPath.to_dict()`` data), builds one FMU per
distinct number of trailers in the client, and provides the task function :func:`run_task` that a
worker runs for each co-simulation.

Python API::

    from pushtrain.cli.sweep import sweep
    outcome = sweep("examples/joint_bias_5deg.toml", "examples/sweeps/joint_bias.toml",
                    "runs/bias_sweep", workers=2)        # or serial=True, client=..., scheduler=...
    outcome.rows, outcome.failures, outcome.files

This module must not import :mod:`pushtrain.cli.main` at import time (workers import it to
unpickle :func:`run_task`, and ``main`` imports this module at its end).
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import click

from pushtrain.files import atomic_write_bytes

from pushtrain.studies.sweep import (
    SweepError,
    SweepOutcome,
    SweepSpec,
    expand_runs,
    get_path,
    load_sweep_spec,
    parse_path,
    resolve,
    run_sweep,
    set_path,
)

from pushtrain.mission.scenario import Scenario, ScenarioError, load_scenario, parse_scenario

__all__ = ["FmuRef", "prepare_runs", "run_task", "sweep", "sweep_cmd"]

log = logging.getLogger(__name__)

_PER_TRAILER = {("sensors", "joint_bias_deg"), ("train", "mass"), ("train", "inertia"),
                ("train", "payload"), ("train", "mu")}
_NOT_FOR_PLANNING = ("mass", "inertia", "payload", "mu")
STATUS_INVALID = "invalid"
STATUS_PLANNING_FAILED = "planning_failed"
MAX_LISTED = 20


@dataclass(frozen=True)
class FmuRef:
    """Where a task finds its FMU: ``path`` on this machine, else bytes shipped under ``sha256``."""

    n: int
    path: str
    sha256: str


def _sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _materialize(ref: FmuRef, shared: dict) -> str:
    """The FMU's path on this worker: the client's path if it holds the same file, else the
    shipped bytes written once to a temporary folder."""
    path = Path(ref.path)
    blob = shared.get(f"fmu-{ref.sha256}")
    if path.is_file() and (blob is None or _sha256(path) == ref.sha256):
        return str(path)
    if blob is None:
        raise FileNotFoundError(f"FMU {ref.path} (n = {ref.n}) is not on this worker and was not "
                                "shipped (use ship_fmu=True for remote clusters)")
    folder = Path(tempfile.gettempdir()) / "pushtrain-sweep-fmu"
    folder.mkdir(parents=True, exist_ok=True)
    target = folder / f"TrailerTrain-n{ref.n}-{ref.sha256[:16]}.fmu"
    if not target.is_file() or _sha256(target) != ref.sha256:
        atomic_write_bytes(target, blob)
    return str(target)


def run_task(payload: dict, shared: dict):
    """Worker side: co-simulate one resolved scenario (no files written); returns the Result.

    ``payload`` holds ``scenario`` (a resolved, validated scenario dict), ``fmu`` (an
    :class:`FmuRef`) and ``path`` (``PlannedPath.to_dict()`` data for ``plan`` missions, else None).
    """
    from pushtrain.mission.runner import run_scenario

    sc = parse_scenario(payload["scenario"], payload["scenario"].get("name", "<run>"))
    fmu = _materialize(payload["fmu"], shared)
    reference = None
    if sc.mission.kind == "plan":
        from pushtrain.planner.path import PlannedPath

        reference = PlannedPath.from_dict(payload["path"]).to_reference(
            speed=sc.planner.speed, cusp_dwell=sc.planner.cusp_dwell)
    return run_scenario(sc, None, reference=reference, progress=False, fmu=fmu)


def _base_dict(sc: Scenario, spec: SweepSpec) -> dict:
    """The fully resolved base scenario; per-trailer single values that a path indexes become
    lists of n (``joint_bias_deg = 0.0`` -> ``[0.0, 0.0, 0.0]``), which means the same."""
    data = sc.model_dump(mode="json")
    n = spec.overrides.get("train.n", sc.train.n)
    for path in [*spec.overrides, *(p.path for p in spec.parameters)]:
        parts = parse_path(path)
        if len(parts) >= 3 and tuple(parts[:2]) in _PER_TRAILER and isinstance(parts[2], int):
            value = data[parts[0]][parts[1]]
            if not isinstance(value, list) and isinstance(n, int):
                data[parts[0]][parts[1]] = [value] * n
    return data


def _check_paths(base: dict, spec: SweepSpec) -> None:
    problems = []
    data = json.loads(json.dumps(base))
    for path, value in spec.overrides.items():
        try:
            set_path(data, path, value)
        except KeyError as exc:
            problems.append((f"overrides.{path!r}", value, exc.args[0]))
    for k, p in enumerate(spec.parameters):
        try:
            get_path(data, p.path)
        except KeyError as exc:
            problems.append((f"parameters[{k}].path", p.path, exc.args[0]))
    if problems:
        raise SweepError(spec.name, problems)


def _planning_key(data: dict) -> str:
    train = {k: v for k, v in data["train"].items() if k not in _NOT_FOR_PLANNING}
    keep = {k: data.get(k) for k in ("map", "start", "goal", "planner", "seed")}
    return json.dumps({"train": train, **keep}, sort_keys=True)


def _bias_swept(spec: SweepSpec) -> bool:
    paths = [*spec.overrides, *(p.path for p in spec.parameters)]
    return any(p.startswith("sensors.joint_bias_deg") for p in paths)


def _predicted(sc: Scenario) -> dict:
    """eps_eff [deg] and the closed-form steady offset [m] (core.analysis, as `analyze`)."""
    from pushtrain.core import analysis

    from pushtrain.mission.runner import bias_model

    c = sc.controller
    link, speed, bias, eps = bias_model(sc)
    if sc.sensors.localize == "last_trailer":
        pred = analysis.steady_lateral_error(eps, link, c.k_y)
    else:
        pred = analysis.steady_lateral_error_estimated_pose(bias, link, c.k_x, c.k_y, c.k_theta,
                                                            speed)
    return {"eps_eff_deg": math.degrees(eps), "predicted_steady_lat_m": float(pred)}


def prepare_runs(sc: Scenario, spec: SweepSpec, *, fmus: dict | None = None,
                 ship_fmu: bool = False):
    """Expand, resolve and validate every run; plan and build FMUs in the client.

    Parameters
    ----------
    sc : Scenario
        The base scenario.
    spec : SweepSpec
    fmus : dict, optional
        ``{n: path}`` FMU files to use instead of :func:`pushtrain.fmu.build_fmu`.
    ship_fmu : bool
        Also return the FMU bytes as shared data (for workers on other machines).

    Returns
    -------
    runs : list of SweepRun
        With ``payload``, ``extras`` and (planning failures) ``failure`` filled in.
    shared : dict
        Data for every task (``fmu-<sha256>`` -> bytes when shipping).
    manifest : dict
        Spec and base scenario (their fingerprint guards resume).

    Raises
    ------
    SweepError
        A path that is not in the scenario, or runs whose resolved scenario is invalid (all
        reported before anything runs).
    """
    from pushtrain.fmu import build_fmu

    base = _base_dict(sc, spec)
    _check_paths(base, spec)
    runs = expand_runs(spec)
    problems, scenarios = [], {}
    for run in runs:
        data = resolve(base, spec.overrides, run.params)
        if spec.seed_per_run:
            data["seed"] = spec.seed + run.index
        try:
            scenarios[run.index] = parse_scenario(data, f"run {run.index}")
        except ScenarioError as exc:
            values = ", ".join(f"{k} = {v!r}" for k, v in run.params.items())
            problems += [(f"run {run.index} ({values}): {where}", value, allowed)
                         for where, value, allowed in exc.errors]
    if problems:
        listed = problems[:MAX_LISTED]
        if len(problems) > MAX_LISTED:
            listed.append(("...", len(problems) - MAX_LISTED, "more problems not listed"))
        raise SweepError(f"{spec.name}: invalid parameter combination(s)", listed)

    refs, shared = {}, {}
    for n in sorted({s.train.n for s in scenarios.values()}):
        path = Path(fmus[n]) if fmus and n in fmus else Path(build_fmu(n))
        refs[n] = FmuRef(n, str(path), _sha256(path))
        if ship_fmu:
            shared[f"fmu-{refs[n].sha256}"] = path.read_bytes()

    plans: dict[str, tuple] = {}
    with_prediction = _bias_swept(spec)
    for run in runs:
        run_sc = scenarios[run.index]
        data = run_sc.model_dump(mode="json")
        path_data = None
        if run_sc.mission.kind == "plan":
            key = _planning_key(data)
            if key not in plans:
                plans[key] = _plan(run_sc)
            path_data, failure = plans[key]
            if failure is not None:
                run.failure = (STATUS_PLANNING_FAILED, failure)
        run.payload = {"scenario": data, "fmu": refs[run_sc.train.n], "path": path_data}
        if with_prediction and run_sc.mission.kind != "rotation":
            run.extras = _predicted(run_sc)
    if plans:
        log.info("planned %d distinct train geometries in the client", len(plans))
    manifest = {"spec": spec.model_dump(mode="json"), "base": base}
    return runs, shared, manifest


def _plan(sc: Scenario):
    from pushtrain.planner import PlanningError

    from pushtrain.mission.runner import plan_path

    try:
        return plan_path(sc).to_dict(), None
    except PlanningError as exc:
        return None, f"planning failed ({getattr(exc, 'reason', '')}): {exc}"


def _quiet_worker_logs():  # runs on each worker of our own LocalCluster
    logging.getLogger("pushtrain").addHandler(logging.NullHandler())
    logging.getLogger("pushtrain").propagate = False


def sweep(scenario, spec, out_dir, *, serial: bool = False, client=None,
          scheduler: str | None = None, workers: int | None = None, max_runs: int | None = None,
          fmus: dict | None = None, ship_fmu: bool | None = None, plots: bool = True,
          on_row=None, on_start=None) -> SweepOutcome:
    """Run a sweep and write its report.

    Parameters
    ----------
    scenario : Scenario or path-like
        The base scenario.
    spec : SweepSpec or path-like
        The sweep specification.
    out_dir : path-like
        Output folder; a folder of an interrupted sweep resumes it.
    serial : bool
        Run every task in this process (same numbers as on a cluster).
    client : distributed.Client, optional
        An existing client to use.
    scheduler : str, optional
        Address of an existing scheduler (``tcp://host:8786``); FMUs are shipped as bytes.
    workers : int, optional
        Worker processes of the LocalCluster started otherwise (default: the number of cores).
    max_runs : int, optional
        Run at most this many new runs (resume later).
    fmus : dict, optional
        ``{n: path}`` FMU files instead of building them.
    ship_fmu : bool, optional
        Ship the FMU bytes to the workers (default: only with ``scheduler`` or ``client``).
    plots : bool
        Write the PNG plots besides ``report.json``.
    on_row : callable, optional
        ``on_row(row, done, total)`` after each finished run.
    on_start : callable, optional
        ``on_start(n_runs)`` once the runs are prepared (before anything runs).

    Returns
    -------
    SweepOutcome
        With ``report`` (the report dict) and ``files`` (results, report, plots, chunks).
    """
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    spec = spec if isinstance(spec, SweepSpec) else load_sweep_spec(spec)
    if ship_fmu is None:
        ship_fmu = not serial and (client is not None or scheduler is not None)
    runs, shared, manifest = prepare_runs(sc, spec, fmus=fmus, ship_fmu=ship_fmu)
    if on_start is not None:
        on_start(len(runs))
    kwargs = dict(metrics=spec.kept_metrics, steady_window=spec.steady_window,
                  chunk_size=spec.chunk_size, shared=shared, max_runs=max_runs,
                  manifest=manifest, on_row=on_row)
    t0 = time.perf_counter()
    if serial:
        outcome = run_sweep(runs, run_task, out_dir, serial=True, **kwargs)
    elif client is not None:
        outcome = run_sweep(runs, run_task, out_dir, client=client, **kwargs)
    else:
        from distributed import Client, LocalCluster

        if scheduler is not None:
            with Client(scheduler) as own:
                outcome = run_sweep(runs, run_task, out_dir, client=own, **kwargs)
        else:
            n_workers = workers or os.cpu_count() or 1
            with LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                              dashboard_address=":0", silence_logs=logging.ERROR) as cluster, \
                    Client(cluster) as own:
                own.run(_quiet_worker_logs)
                outcome = run_sweep(runs, run_task, out_dir, client=own, **kwargs)
    elapsed = time.perf_counter() - t0
    from pushtrain.studies.sweep_report import write_report

    parameters = [{"path": p.path, "label": p.label} for p in spec.parameters]
    extra = {"mode": spec.mode, "new_runs": outcome.new, "resumed_runs": outcome.skipped,
             "elapsed_s": round(elapsed, 3)}
    if _bias_swept(spec):
        forms = {"last_trailer": "exact sin(eps_eff)/(D K_y) (last trailer localized)",
                 "robot": "estimated pose (steady_lateral_error_estimated_pose)"}
        used = sorted({run.payload["scenario"]["sensors"]["localize"] for run in runs})
        extra["prediction_form"] = "; ".join(forms[u] for u in used)
    outcome.report = write_report(outcome.out_dir, outcome.rows, parameters, n_runs=outcome.n_runs,
                                  name=spec.name, description=spec.description, plots=plots,
                                  extra=extra)
    outcome.files.update(report=outcome.report["files"]["report"],
                         plots=outcome.report["files"]["plots"])
    return outcome


# ------------------------------------------------------------------------------------------ CLI
@click.command("sweep")
@click.argument("scenario", type=click.Path(exists=True, dir_okay=False))
@click.option("--spec", "spec_path", type=click.Path(exists=True, dir_okay=False), required=True,
              metavar="SWEEP.toml", help="The sweep specification (parameters, mode, metrics).")
@click.option("--scheduler", metavar="ADDR",
              help="Use an existing Dask scheduler (tcp://host:8786); FMUs are shipped as bytes.")
@click.option("--workers", type=click.IntRange(min=0), metavar="N",
              help="Worker processes of the local cluster (default: one per core); 0 runs "
                   "serially in this process.")
@click.option("--out", "-o", "out", type=click.Path(file_okay=False), metavar="DIR",
              help="Output folder (default runs/<spec name>-<timestamp>/); give the folder of an "
                   "interrupted sweep to resume it.")
@click.option("--max-runs", type=click.IntRange(min=1), metavar="N",
              help="Run at most N new runs, then stop (resume later with the same --out).")
@click.option("--no-plots", is_flag=True, help="Skip the PNG plots.")
def sweep_cmd(scenario, spec_path, scheduler, workers, out, max_runs, no_plots):
    """Robustness sweep of SCENARIO over the parameters of a sweep spec, on Dask.

    Every run is one co-simulation; failures (jackknife, errors) are recorded, not fatal.
    Results go to DIR/results.csv (and chunks/ as they finish), report.json and plots of
    success rate, tracking error and F_lat against each parameter.

    \b
    Examples:
      pushtrain sweep examples/joint_bias_5deg.toml --spec examples/sweeps/joint_bias.toml
      pushtrain sweep examples/joint_bias_5deg.toml --spec examples/sweeps/alternating_sign.toml
      pushtrain sweep SCENARIO --spec SWEEP.toml --workers 0 --out runs/s   # serial
      pushtrain sweep SCENARIO --spec SWEEP.toml --scheduler tcp://host:8786 --out runs/s
    Run the same command with the same --out again to resume an interrupted sweep.
    """
    from tqdm import tqdm

    from pushtrain.fmu import FmuBuildError

    from .common import EXIT_OK, BadInput, _scenario

    sc = _scenario(scenario)
    try:
        spec = load_sweep_spec(spec_path)
    except SweepError as exc:
        raise BadInput(str(exc)) from None
    if scheduler is not None and workers is not None and workers > 0:
        raise BadInput("--workers N starts a local cluster; it cannot be combined with --scheduler")
    out_dir = Path(out) if out else Path("runs") / f"{spec.name}-{time.strftime('%Y%m%d-%H%M%S')}"
    bar = None
    failed = 0

    def on_start(n_runs):
        nonlocal bar
        bar = tqdm(total=n_runs, unit="run", desc="sweep", file=sys.stderr,
                   disable=not sys.stderr.isatty(), mininterval=0.2)

    def on_row(row, done, total):
        nonlocal failed
        if bar is not None:
            if bar.total != total:
                bar.reset(total=total)
            bar.update(1)
            if not row["ok"]:
                failed += 1
                bar.set_postfix_str(f"{failed} failed")

    try:
        outcome = sweep(sc, spec, out_dir, serial=workers == 0, scheduler=scheduler,
                        workers=workers or None, max_runs=max_runs, plots=not no_plots,
                        on_row=on_row, on_start=on_start)
    except (SweepError, ScenarioError) as exc:
        raise BadInput(str(exc)) from None
    except FmuBuildError as exc:
        raise click.ClickException(str(exc)) from None
    finally:
        if bar is not None:
            bar.close()
    _print_outcome(outcome, spec)
    sys.exit(EXIT_OK)


def _print_outcome(outcome: SweepOutcome, spec: SweepSpec) -> None:
    from pushtrain.studies.sweep_report import table_text

    report = outcome.report
    parameters = [{"path": p.path, "label": p.label} for p in spec.parameters]
    click.echo(f"sweep {spec.name}: {outcome.n_runs} runs ({spec.mode}); {outcome.new} run now, "
               f"{outcome.skipped} resumed from earlier chunks")
    click.echo(table_text(outcome.rows, parameters))
    rate = report.get("success_rate")
    click.echo(f"success: {report['ok']}/{report['completed_runs']}"
               + (f" ({rate * 100:.0f} %)" if rate is not None else "")
               + f"; runs with slip: {report['runs_with_slip']}")
    if "bias_prediction" in report:
        bp = report["bias_prediction"]
        click.echo(f"steady offset vs {report.get('prediction_form', 'prediction')}: "
                   f"max deviation {bp['max_abs_deviation_m'] * 100:.2f} cm over {bp['runs']} runs")
    failures = outcome.failures
    if failures:
        click.echo(f"{len(failures)} failed run(s):")
        for row in failures[:8]:
            values = ", ".join(f"{p['path']} = {row.get(p['path'])!r}" for p in parameters)
            click.echo(f"  run {row['index']} ({values}): {row['status']}: {row['error'][:110]}")
        if len(failures) > 8:
            click.echo(f"  ... and {len(failures) - 8} more (report.json)")
    if not outcome.complete:
        click.echo(f"incomplete: {outcome.n_runs - len(outcome.rows)} run(s) still to do; "
                   "run the same command with the same --out to resume")
    click.echo(f"results: {outcome.out_dir}")
