"""One context manager for the folder of one run: :func:`run_folder`."""

from __future__ import annotations

import contextlib
import json
import logging
import re
import time
from contextlib import contextmanager
from pathlib import Path

import click

from pushtrain.errors import InputError, PlanningError, PushtrainError
from pushtrain.files import atomic_write_text, claim_run_folder, remove_partials

from .common import BadInput, click_error
from .exits import EXIT_BAD_INPUT, EXIT_NOT_REACHED, interruption
from .logs import to_run_log

__all__ = ["run_folder", "default_folder", "STATUS_INVALID", "STATUS_PLANNING_FAILED",
           "STATUS_FAILED", "STATUS_ERROR", "STATUS_INTERRUPTED"]

log = logging.getLogger(__name__)

# summary.json status of a run that ended before the co-simulation wrote its own summary
STATUS_INVALID = "invalid"                  # bad input found late (exit 2)
STATUS_PLANNING_FAILED = "planning_failed"  # no plan found (exit 1; 2 if proven impossible)
STATUS_FAILED = "failed"                    # another run-time failure, e.g. an FMU build (exit 1)
STATUS_ERROR = "error"                      # an unexpected exception (a bug; traceback, exit 1)
STATUS_INTERRUPTED = "interrupted"          # Ctrl-C (exit 130) or SIGTERM (exit 143)


def default_folder(name: str) -> Path:
    """``runs/<name>-<timestamp>`` (``-2``, ``-3``, ... appended if taken); the name is reduced
    to letters, digits, ``.``, ``_`` and ``-``."""
    safe = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._")[:60] or "run"
    base = Path("runs") / f"{safe}-{time.strftime('%Y%m%d-%H%M%S')}"
    path, k = base, 1
    while path.exists():
        k += 1
        path = base.with_name(f"{base.name}-{k}")
    return path


def _status_of(exc: PushtrainError, exit_code: int) -> str:
    if isinstance(exc, PlanningError) and exc.details.get("impossible"):
        # bad input (exit 2), but a failed plan all the same: its page, picture and bag
        # (export-bag reads the status) show where no way of the train's width goes
        return STATUS_PLANNING_FAILED
    if exit_code == EXIT_BAD_INPUT:
        return STATUS_INVALID
    return STATUS_PLANNING_FAILED if isinstance(exc, PlanningError) else STATUS_FAILED


def _record_failure(out_dir: Path, sc, status: str, message: str, exit_code: int) -> None:
    """Log how the run ended and, unless the run wrote its own, write a summary.json saying so."""
    log.info("run ended: %s (exit %d): %s", status, exit_code, message)
    summary_path = out_dir / "summary.json"
    if summary_path.exists():
        return
    summary = {"status": status, "message": message, "exit_code": exit_code}
    if sc is not None:
        summary.update(scenario=sc.name, mission=sc.mission.kind)
    try:
        atomic_write_text(summary_path, json.dumps(summary, indent=2))
    except OSError as exc:  # must not hide the failure being recorded
        log.warning("could not write %s: %s", summary_path, exc)


@contextmanager
def _claimed(path: Path, out: str | None):
    """:func:`~pushtrain.files.claim_run_folder`, its refusals as BadInput (naming --out)."""
    held = contextlib.ExitStack()
    try:
        held.enter_context(claim_run_folder(path))
    except InputError as exc:
        raise BadInput(f"--out: {exc}" if out is not None else str(exc)) from None
    with held:
        yield path


@contextmanager
def run_folder(out: str | None, name: str, sc=None):
    """The folder of one run, holding that run's files only.

    Makes ``out`` (default :func:`default_folder`) a fresh run folder, held for the block
    (:func:`pushtrain.files.claim_run_folder`: a previous run there is replaced; a folder
    another run is writing, a folder of other files or an impossible path is bad input), logs
    into its ``run.log`` for the duration of the block and removes that handler afterwards. If
    the block fails, the failure goes to ``run.log`` and into ``summary.json`` (status
    ``invalid``, ``planning_failed``, ``failed``, ``error`` or, on Ctrl-C or SIGTERM,
    ``interrupted`` with exit code 130 or 143), and pushtrain's errors become click exceptions
    with the right exit code. ``--out ""`` is refused, not taken for the default.
    """
    if out is not None and not out.strip():
        raise BadInput(f"--out {out!r}: an empty folder name; allowed: a folder path, or no "
                       "--out for runs/<name>-<timestamp>")
    path = Path(out) if out is not None else default_folder(name)
    with _claimed(path, out), to_run_log(path):
        log.info("run folder %s", path.resolve())
        try:
            yield path
        except PushtrainError as exc:
            err = click_error(exc)
            _record_failure(path, sc, _status_of(exc, err.exit_code), err.format_message(),
                            err.exit_code)
            raise err from None
        except click.ClickException as exc:
            status = STATUS_INVALID if exc.exit_code == EXIT_BAD_INPUT else STATUS_FAILED
            _record_failure(path, sc, status, exc.format_message(), exc.exit_code)
            raise
        except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (cli.exits.Terminated)
            remove_partials()
            code, what = interruption(exc)
            message = f"{what}: the files written so far are kept"
            _record_failure(path, sc, STATUS_INTERRUPTED, message, code)
            click.echo(f"{message} in {path}", err=True)
            raise click.exceptions.Exit(code) from None
        except Exception as exc:
            log.info("unexpected error", exc_info=True)
            _record_failure(path, sc, STATUS_ERROR, f"{type(exc).__name__}: {exc}",
                            EXIT_NOT_REACHED)
            raise
