"""``pushtrain sweep``: robustness sweeps of a scenario on Dask (or serially).

The command and its printing only; the sweep itself (spec, runs, execution, resume, report) is
:mod:`pushtrain.studies.sweep`.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

import click

from pushtrain.errors import ScenarioError, SweepError
from pushtrain.limits import SWEEP_MAX_TOTAL

if TYPE_CHECKING:  # the sweep's modules (pydantic, numpy, Dask) load when a sweep runs
    from pushtrain.studies.sweep_results import SweepOutcome
    from pushtrain.studies.sweep_spec import SweepSpec

from .common import workers_option

__all__ = ["sweep_cmd", "check_scheduler"]


# ------------------------------------------------------------------------------------------ CLI
def check_scheduler(address: str) -> None:
    """Raise BadInput naming ``--scheduler`` unless ``address`` is a Dask address whose host
    accepts connections (:func:`pushtrain.studies.sweep.scheduler_problem`)."""
    from pushtrain.studies import sweep as sweep_lib

    from .common import BadInput

    problem = sweep_lib.scheduler_problem(address)
    if problem:
        raise BadInput(f"--scheduler = {address!r}: {problem}")


PIPE_INTERVAL_S = 10.0
"""Seconds between progress lines when stderr is not a terminal (a pipe, a log file)."""


class _Progress:
    """Progress of the runs on stderr: a tqdm bar on a terminal; elsewhere one line at most every
    ``interval`` seconds and one when the last run is done. ``start`` and ``row`` are
    :func:`~pushtrain.studies.sweep.sweep`'s ``on_start`` and ``on_row``."""

    def __init__(self, *, tty: bool, interval: float = PIPE_INTERVAL_S, clock=time.monotonic):
        self.tty, self.interval, self.clock = tty, interval, clock
        self.bar = None
        self.done = self.total = self.failed = 0
        self.t0 = self.last = 0.0

    def start(self, n_runs: int) -> None:
        self.t0 = self.last = self.clock()
        if self.tty:
            from tqdm import tqdm

            self.bar = tqdm(total=n_runs, unit="run", desc="sweep", file=sys.stderr,
                            mininterval=0.2)

    def row(self, row: dict, done: int, total: int) -> None:
        self.done, self.total = done, total
        self.failed += not row["ok"]
        if self.bar is not None:
            if self.bar.total != total:
                self.bar.reset(total=total)
            self.bar.update(1)
            if self.failed:
                self.bar.set_postfix_str(f"{self.failed} failed")
            return
        now = self.clock()
        if done == total or now - self.last >= self.interval:
            self.last = now
            click.echo(self.line(now), err=True)

    def line(self, now: float) -> str:
        elapsed = now - self.t0
        text = (f"sweep: {self.done}/{self.total} new runs done, {self.failed} failed, "
                f"{elapsed:.0f} s")
        if 0 < self.done < self.total:
            text += f", about {elapsed / self.done * (self.total - self.done):.0f} s left"
        return text

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


@click.command("sweep")
@click.argument("scenario", type=click.Path(exists=True, dir_okay=False))
@click.option("--spec", "spec_path", type=click.Path(exists=True, dir_okay=False), required=True,
              metavar="SWEEP.toml", help="The sweep specification (parameters, mode, metrics).")
@click.option("--scheduler", metavar="ADDR",
              help="Use an existing Dask scheduler (tcp://host:8786); FMUs are shipped as bytes.")
@workers_option
@click.option("--out", "-o", "out", type=click.Path(file_okay=False), metavar="DIR",
              help="Output folder (default runs/<spec name>-<timestamp>/); give the folder of an "
                   "interrupted sweep to resume it.")
@click.option("--max-runs", type=click.IntRange(min=1), metavar="N",
              help="Run at most N new runs, then stop (resume later with the same --out).")
@click.option("--max-total", type=click.IntRange(min=1), default=SWEEP_MAX_TOTAL,
              show_default=True, metavar="N",
              help="Refuse a spec that makes more than N runs (counted before anything runs).")
@click.option("--no-plots", is_flag=True, help="Skip the PNG plots.")
def sweep_cmd(scenario, spec_path, scheduler, workers, out, max_runs, max_total, no_plots):
    """Robustness sweep of SCENARIO over the parameters of a sweep spec, on Dask.

    Every run is one co-simulation; failures (jackknife, errors) are recorded, not fatal.
    Results go to DIR/results.csv (and chunks/ as they finish), report.json and plots of
    success rate, tracking error and F_lat against each parameter. The number of runs is
    printed before anything runs; progress goes to stderr. Ctrl-C stops the sweep, keeps the
    rows done and exits with 130.

    \b
    Examples:
      pushtrain sweep examples/joint_bias_5deg.toml --spec examples/sweeps/joint_bias.toml
      pushtrain sweep examples/joint_bias_5deg.toml --spec examples/sweeps/alternating_sign.toml
      pushtrain sweep SCENARIO --spec SWEEP.toml --workers 0 --out runs/s   # serial
      pushtrain sweep SCENARIO --spec SWEEP.toml --scheduler tcp://host:8786 --out runs/s
    Run the same command with the same --out again to resume an interrupted sweep.
    """
    from pushtrain.errors import FmuBuildError
    from pushtrain.studies import sweep as sweep_lib
    from pushtrain.studies.sweep_spec import count_runs, load_sweep_spec

    from .common import BadInput, load_scenario_with_overrides, local_workers, writable_folder
    from .exits import EXIT_OK, interruption

    if out is not None and not out.strip():
        raise BadInput(f"--out {out!r}: an empty folder name; allowed: a folder path, or no "
                       "--out for runs/<name>-<timestamp>")
    sc = load_scenario_with_overrides(scenario)
    try:
        spec = load_sweep_spec(spec_path)
    except SweepError as exc:
        raise BadInput(str(exc)) from None
    workers = local_workers(workers, scheduler)
    if scheduler is not None and workers != 0:
        check_scheduler(scheduler)
    out_dir = Path(out) if out else Path("runs") / f"{spec.name}-{time.strftime('%Y%m%d-%H%M%S')}"
    writable_folder("--out", str(out_dir))
    click.echo(f"sweep {spec.name}: {count_runs(spec)} runs ({spec.size_text}) "
               f"-> {out_dir}")
    progress = _Progress(tty=sys.stderr.isatty())
    try:
        outcome = sweep_lib.sweep(sc, spec, out_dir, serial=workers == 0, scheduler=scheduler,
                                  workers=workers or None, max_runs=max_runs,
                                  plots=not no_plots, max_total=max_total, on_row=progress.row,
                                  on_start=progress.start)
    except (SweepError, ScenarioError) as exc:
        raise BadInput(str(exc)) from None
    except FmuBuildError as exc:
        raise click.ClickException(str(exc)) from None
    except KeyboardInterrupt as exc:  # Ctrl-C (130), or SIGTERM (cli.exits.Terminated: 143)
        progress.close()
        code, what = interruption(exc)
        click.echo(f"{what}: {progress.done} new run(s) kept in {out_dir}; run the same "
                   "command with the same --out to resume", err=True)
        sys.exit(code)
    finally:
        progress.close()
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
        click.echo(f"incomplete: {outcome.remaining} run(s) still to do; "
                   "run the same command with the same --out to resume")
    click.echo(f"results: {outcome.out_dir}")
