"""The console scripts ``pushtrain`` and ``plan-and-run``.

They load the CLI (:mod:`pushtrain.cli.main`) inside a guard, so that Ctrl-C at any moment,
while the modules load included, ends the command with one line on stderr and exit code 130
(as a shell reports an interrupted program), never a traceback or click's "Aborted!" with the
exit code 1 that means "the run did not reach its goal".
"""

from __future__ import annotations

import sys

from .exits import EXIT_INTERRUPTED


def _interrupted() -> None:
    sys.stderr.write("\ninterrupted (Ctrl-C)\n")
    sys.exit(EXIT_INTERRUPTED)


def _run(name: str) -> None:
    """Load ``pushtrain.cli.main.<name>`` and run it as click's standalone mode would, with
    Ctrl-C as exit 130."""
    try:
        import click

        from . import main

        try:
            code = getattr(main, name)(standalone_mode=False)
        except click.exceptions.Abort:
            _interrupted()
        except click.ClickException as exc:
            exc.show()
            sys.exit(exc.exit_code)
    except KeyboardInterrupt:
        _interrupted()
    sys.exit(code if isinstance(code, int) else 0)


def pushtrain() -> None:
    """``pushtrain COMMAND ...``."""
    _run("pushtrain_main")


def plan_and_run() -> None:
    """``plan-and-run SCENARIO ...``: the main job on its own."""
    _run("plan_and_run_main")
