"""What the commands share: exit codes, the bad-input exception, loading a scenario, turning
pushtrain's errors into exit codes, and the common arguments and options."""

from __future__ import annotations

import contextlib
import logging
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import click

from pushtrain.errors import InputError, PlanningError, PushtrainError, ScenarioError
from pushtrain.fmu.variables import MAX_TRAILERS

from .exits import EXIT_BAD_INPUT, EXIT_NOT_REACHED

if TYPE_CHECKING:  # the scenario's models (pydantic, numpy) load when a command reads one
    from pushtrain.mission.scenario import Scenario

__all__ = ["BadInput", "load_scenario_with_overrides", "check_map", "click_error", "click_errors",
           "scenario_argument", "out_dir_option", "trailers_option", "csv_option",
           "workers_option", "local_workers", "usable_cores", "writable_folder"]

# planning failures that are the scenario's fault (exit 2); the others mean no plan was found.
# A goal no way of the train's width reaches ("impossible here", details["impossible"]) is one
# too: it is proven from the map before any search, not a search that gave up.
_INPUT_REASONS = {"start_in_collision", "goal_in_collision", "no_free_space"}


def _scenario_fault(exc: PlanningError) -> bool:
    """Whether a planning failure is the scenario's fault (bad input, exit 2)."""
    return exc.reason in _INPUT_REASONS or bool(exc.details.get("impossible"))

log = logging.getLogger("pushtrain.cli")


class BadInput(click.ClickException):
    """Bad input: the message names the field, the value and what is allowed (exit 2)."""

    exit_code = EXIT_BAD_INPUT


def load_scenario_with_overrides(path: str, trailers: int | None = None,
                                 seed: int | None = None) -> Scenario:
    """Load the scenario at ``path`` with the command line's overrides, or raise BadInput."""
    from pushtrain.mission.scenario import load_scenario, parse_scenario

    try:
        sc = load_scenario(path)
        if trailers is not None or seed is not None:
            data = sc.model_dump()
            if trailers is not None:
                data["train"]["n"] = trailers
                for key in ("front", "rear"):
                    data["train"][key] = None
                for key in ("mass", "inertia", "payload", "mu"):
                    if isinstance(data["train"][key], list):
                        raise ScenarioError(path, [(f"train.{key}", data["train"][key],
                                                    "a single value when --trailers overrides n")])
            if seed is not None:
                data["seed"] = seed
            sc = parse_scenario(data, path)
        return sc
    except ScenarioError as exc:
        raise BadInput(str(exc)) from None


def check_map(sc: Scenario) -> None:
    """Raise BadInput when the map is malformed or the start or goal lies outside it."""
    from pushtrain.mission.runner import check_start_in_map

    try:
        check_start_in_map(sc)
    except ScenarioError as exc:
        raise BadInput(str(exc)) from None
    except ValueError as exc:  # the planner's input errors (bad polygons)
        raise BadInput(f"{sc.name}: map: {exc}") from None


def click_error(exc: PushtrainError) -> click.ClickException:
    """The click exception for one of pushtrain's errors: exit 2 for bad input (including a
    start or goal in collision, and a goal proven impossible to reach), 1 for a run-time
    failure (no plan found by the search, an FMU build)."""
    planning = isinstance(exc, PlanningError)
    text = f"planning failed ({exc.reason}): {exc.message}" if planning else str(exc)
    if isinstance(exc, InputError) or planning and _scenario_fault(exc):
        return BadInput(text)
    err = click.ClickException(text)
    err.exit_code = EXIT_NOT_REACHED
    return err


@contextmanager
def click_errors():
    """Turn pushtrain's errors raised inside into click exceptions (:func:`click_error`)."""
    try:
        yield
    except PushtrainError as exc:
        raise click_error(exc) from None


scenario_argument = click.argument("scenario", type=click.Path(exists=True, dir_okay=False))
out_dir_option = click.option(
    "--out", "-o", "out", type=click.Path(file_okay=False), metavar="DIR",
    help="Output folder: new, empty or a previous run's (replaced); default "
         "runs/<name>-<timestamp>/.")
trailers_option = click.option("--trailers", type=click.IntRange(1, MAX_TRAILERS), metavar="N",
                               help="Override train.n.")
csv_option = click.option("--csv", "csv", is_flag=True,
                          help="Also write results.csv (the results.npz table as text).")
plot_processes_option = click.option(
    "--plot-processes", "plot_processes", type=click.IntRange(0, 2), default=None, metavar="N",
    help="Processes that draw the plots and the GIF beside this one (0: draw here, the least "
         "memory; default: 2 on two or more cores, else 1).")



def usable_cores() -> int:
    """The cores this process may use (its CPU affinity where the system tells it)."""
    import os

    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


workers_option = click.option(
    "--workers", type=click.IntRange(min=0), default=None, metavar="K",
    help="Worker processes of the local Dask cluster (default: one per core; more than the "
         "cores are capped to them); 0 runs serially in this process, without Dask.")


def local_workers(workers: int | None, scheduler: str | None) -> int | None:
    """``--workers`` checked against ``--scheduler`` and capped by the machine: None for the
    default (one per core), 0 for serial, else at most :func:`usable_cores` (saying so on
    stderr when capped). A positive count with ``--scheduler`` is refused (the cluster is
    there already)."""
    if workers is None or workers == 0:
        return workers
    if scheduler is not None:
        raise BadInput(f"--workers {workers}: it sizes a local cluster and cannot be combined "
                       f"with --scheduler {scheduler!r}; allowed: --workers 0 (serial) or no "
                       "--workers")
    cores = usable_cores()
    if workers > cores:
        click.echo(f"--workers {workers}: more than the {cores} core(s) this process may use "
                   f"(each worker is a process running one co-simulation); starting {cores}",
                   err=True)
        return cores
    return workers


PATH_MAX = 4096
"""The longest path Linux opens [bytes]."""
INSIDE_PATH_BYTES = 256
"""Room [bytes] kept for what a command writes inside its output folder (sub-folders, names)."""


def writable_folder(option: str, out: str) -> Path:
    """The output folder ``out`` checked writable before any work (made with its parents for
    a probe file, then removed again), or BadInput naming ``option``: an empty name, a file, a
    name or path too long, a place where nothing can be written."""
    import errno
    import os
    import tempfile

    from pushtrain.validation import clip_text

    shown = clip_text(str(out), 120)
    if not str(out).strip():
        raise BadInput(f"{option} {out!r}: an empty folder name; allowed: a folder path")
    path = Path(out)
    made = []  # the folders made for the probe, deepest first: removed again
    try:
        if path.exists() and not path.is_dir():
            raise BadInput(f"{option} {shown}: is a file; allowed: a folder path")
        if len(os.fsencode(os.path.abspath(path))) > PATH_MAX - INSIDE_PATH_BYTES:
            raise OSError(errno.ENAMETOOLONG, f"too long for the files written inside "
                          f"(at most {PATH_MAX - INSIDE_PATH_BYTES} bytes)")
        missing = path
        while not missing.exists() and missing != missing.parent:
            made.append(missing)
            missing = missing.parent
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=path, prefix=".pushtrain-probe-"):
            pass
    except OSError as exc:
        raise BadInput(f"{option} {shown}: cannot be written: {exc.strerror or exc}; allowed: "
                       "a folder that can be created and written (each name at most 255 bytes, "
                       "the path at most 4096)") from None
    finally:
        for folder in made:  # a refusal, or the work that follows, finds things as they were
            with contextlib.suppress(OSError):
                folder.rmdir()
    return path
