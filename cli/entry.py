"""The console scripts ``pushtrain`` and ``plan-and-run``.

They load the CLI (:mod:`pushtrain.cli.main`) inside a guard, so that Ctrl-C at any moment,
while the modules load included, ends the command with one line on stderr and exit code 130
(as a shell reports an interrupted program), never a traceback or click's "Aborted!" with the
exit code 1 that means "the run did not reach its goal". SIGTERM (``kill``, ``docker stop``, a
batch scheduler) is handled as Ctrl-C is, with exit code 143.
"""

from __future__ import annotations

import sys

from .exits import interruption, terminate_as_interrupt

__all__ = ["pushtrain", "plan_and_run"]


def _interrupted(exc: BaseException | None) -> None:
    code, what = interruption(exc)
    sys.stderr.write(f"\n{what}\n")
    sys.exit(code)


def _run(name: str) -> None:
    """Load ``pushtrain.cli.main.<name>`` and run it as click's standalone mode would, with
    Ctrl-C as exit 130 and SIGTERM as exit 143."""
    terminate_as_interrupt()
    try:
        import click

        from . import main

        try:
            code = getattr(main, name)(standalone_mode=False)
        except click.exceptions.Abort as exc:  # click's word for a KeyboardInterrupt
            _interrupted(exc.__context__)
        except click.ClickException as exc:
            exc.show()
            sys.exit(exc.exit_code)
    except KeyboardInterrupt as exc:
        _interrupted(exc)
    sys.exit(code if isinstance(code, int) else 0)


def pushtrain() -> None:
    """``pushtrain COMMAND ...``."""
    _run("pushtrain_main")


def plan_and_run() -> None:
    """``plan-and-run SCENARIO ...``: the main job on its own."""
    _run("plan_and_run_main")
