"""What a run draws: the options (``--plots page|all|none``, ``--gif``, the older ``--no-plots``
and ``--no-gif``), the files they ask for, and ``report.html`` written in the command's own
process from the data (no matplotlib). The PNGs and the GIF are drawn by
:mod:`pushtrain.cli.plotting`."""

from __future__ import annotations

import logging
import time

from pushtrain.report import GIF_FILE, HTML_FILE, PNG_FILES  # names only: no matplotlib here

from .plotting import PlotProblem, one_line, run_of

__all__ = ["PLOTS_CHOICES", "pictures_options", "chosen_files", "draw_page"]

log = logging.getLogger(__name__)

PLOTS_CHOICES = ("page", "all", "none")
"""``--plots``: ``page`` report.html only (the default: no matplotlib), ``all`` report.html and
the four PNGs, ``none`` no picture at all."""


def pictures_options(command):
    """``--plots page|all|none``, ``--gif``, and the older ``--no-plots`` and ``--no-gif``
    (which keep their meaning) on a click ``command``."""
    import click

    for option in reversed((
        click.option("--plots", "plots", type=click.Choice(PLOTS_CHOICES), default=None,
                     help="What to draw: page = report.html (default), all = report.html and "
                          f"the PNGs ({', '.join(PNG_FILES)}), none = nothing."),
        click.option("--gif", "gif", is_flag=True,
                     help=f"Also write the animation {GIF_FILE}."),
        click.option("--no-plots", "no_plots", is_flag=True,
                     help="Draw nothing (the same as --plots none)."),
        click.option("--no-gif", "no_gif", is_flag=True,
                     help="No animation (the default; for older scripts)."),
    )):
        command = option(command)
    return command


def chosen_files(plots: str | None, gif: bool | None, no_plots: bool = False,
                 no_gif: bool = False) -> tuple[str, ...]:
    """The picture files the options ask for, in the order :data:`PNG_FILES`, the GIF,
    report.html; raises click's BadParameter (exit 2) for options that contradict each
    other."""
    import click

    if no_plots and plots not in (None, "none"):
        raise click.BadParameter(f"--no-plots draws nothing, --plots {plots} draws pictures: "
                                 "give one of them", param_hint="'--no-plots'")
    if no_gif and gif:
        raise click.BadParameter("--gif and --no-gif contradict each other: give one",
                                 param_hint="'--gif'")
    plots = "none" if no_plots else (plots or "page")
    if plots == "none":
        if gif:
            raise click.BadParameter("--gif needs pictures: --plots none (or --no-plots) draws "
                                     "nothing", param_hint="'--gif'")
        return ()
    return (PNG_FILES if plots == "all" else ()) + ((GIF_FILE,) if gif else ()) + (HTML_FILE,)


def draw_page(sc, out_dir, result, path=None) -> PlotProblem | None:
    """Write ``report.html`` of a run of ``sc`` into ``out_dir`` in this process (data and the
    bundled renderer, no matplotlib; a few tenths of a CPU-second); what went wrong, if
    anything (the traceback goes to ``run.log``)."""
    from pushtrain.report.data import finite_note
    from pushtrain.report.html import plot_report  # numpy and Pillow only

    wall, cpu = time.perf_counter(), time.process_time()
    try:
        note = finite_note(result.data)
        if note:  # a diverged run: the page draws what is finite and says so too
            log.warning("the results hold values that are %s", note)
        run = run_of(sc, out_dir, result, path)
        plot_report(result.data, run.n, run.out_dir / HTML_FILE, world=run.world,
                    path_xy=run.path_xy, footprints=run.footprints, status=run.status,
                    summary=run.summary, phi_max_deg=run.phi_max_deg, keep_out=run.keep_out)
    except Exception as exc:
        log.debug("drawing %s failed", HTML_FILE, exc_info=True)
        return PlotProblem(HTML_FILE, one_line(exc))
    log.info("%s drawn in %.3f s (CPU %.3f s) by the main process", HTML_FILE,
             time.perf_counter() - wall, time.process_time() - cpu)
    return None
