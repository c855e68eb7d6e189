"""``pushtrain view RUN_DIR``: open a run's ``report.html`` in the default browser."""

from __future__ import annotations

from pathlib import Path

import click

from ..exits import EXIT_BAD_INPUT

__all__ = ["view_cmd"]


def _has_browser() -> bool:
    """Whether Python's webbrowser module knows a browser to start (none on a bare server)."""
    import webbrowser

    try:
        webbrowser.get()
    except webbrowser.Error:
        return False
    return True


@click.command("view", short_help="Open a run's report.html in the default browser.")
@click.argument("run_dir", type=click.Path(file_okay=True, dir_okay=True))
@click.option("--print-path", "print_only", is_flag=True,
              help="Only print the page's path (also what happens where no browser is known).")
def view_cmd(run_dir, print_only):
    """Open RUN_DIR/report.html (the run's map, train, plots and summary) in the default
    browser; where there is none (a server, a container), print its path to open elsewhere.

    \b
    Example:
      pushtrain view runs/l_corridor
    """
    path = Path(run_dir)
    page = path / "report.html" if path.is_dir() or path.suffix != ".html" else path
    if not page.is_file():
        what = ("is not a folder" if not path.exists() else
                "has no report.html (a run with --no-plots, a run stopped before its plots, "
                "or one from before pushtrain wrote it)")
        click.echo(f"Error: RUN_DIR = {run_dir!r} {what}; give a run folder written by "
                   "plan-and-run or run", err=True)
        raise SystemExit(EXIT_BAD_INPUT)
    uri = page.resolve().as_uri()
    if print_only:
        click.echo(page.resolve())
        return
    import webbrowser

    if not _has_browser() or not webbrowser.open(uri):
        click.echo(f"no browser found here; open {uri} in one", err=True)
        click.echo(page.resolve())
        return
    click.echo(f"opened {page.resolve()}")
