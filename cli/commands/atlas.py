"""``pushtrain atlas FACILITY``: which stations a train reaches, with how many trailers."""

from __future__ import annotations

import sys

import click

from ..common import click_errors, workers_option

__all__ = ["atlas_cmd"]


class _Progress:
    """One line on stderr per finished pair, with the estimate of the time left. The atlas's
    first call (before any work) says how many pairs an earlier run had answered already."""

    def __init__(self, out):
        self.out = out
        self.resumed = None

    def __call__(self, done: int, total: int, elapsed: float) -> None:
        if self.resumed is None:
            self.resumed = done
            if done:
                click.echo(f"atlas: resuming in {self.out}: {done} pair(s) answered before are "
                           "kept", err=True)
        if done == self.resumed or elapsed <= 0.0:
            click.echo(f"atlas: {done}/{total} pairs", err=True)
            return
        left = elapsed / (done - self.resumed) * (total - done)
        click.echo(f"atlas: {done}/{total} pairs, {elapsed:.0f} s, about {left:.0f} s left",
                   err=True)


@click.command("atlas", short_help="Which stations a train reaches, with how many trailers.")
@click.argument("facility", type=click.Path(exists=True, dir_okay=False))
@click.option("--trailers", default="1-5", show_default=True, metavar="RANGE",
              help="Trailer counts to try: a range (1-5), a count, or counts (1,3,5).")
@click.option("--out", "-o", "out", required=True, type=click.Path(), metavar="DIR",
              help="Output folder: new, empty, or an earlier atlas of the same facility and "
                   "--trailers (resumed).")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="A running Dask scheduler (default: a LocalCluster on this machine).")
@workers_option
@click.option("--serial", is_flag=True, help="Run in this process, without Dask (as --workers 0).")
@click.option("--stations", "only", default=None, metavar="A,B,...",
              help="Only the pairs among these stations.")
def atlas_cmd(facility, trailers, out, scheduler, workers, serial, only):
    """For every ordered pair of FACILITY's stations and each trailer count, plan and
    co-simulate the mission as plan-and-run does; the answer of a pair is the most trailers
    that reach the goal. Writes atlas.json, atlas.csv, missions/FROM-TO-nK.toml (each replays
    with plan-and-run), atlas.png, matrix.png and report.html into DIR.

    \b
    Example:
      pushtrain atlas examples/atlas/facility.toml --trailers 1-5 --out runs/atlas
    """
    from pushtrain.studies.atlas import AtlasError, atlas, load_facility, parse_trailers

    from ..common import BadInput, local_workers, writable_folder
    from ..sweep import check_scheduler

    if not str(out).strip():
        raise BadInput("--out = '': give the atlas's output folder")
    with click_errors():
        counts = parse_trailers(trailers)
        fac = load_facility(facility)
        chosen = None
        if only is not None:
            chosen = tuple(s.strip() for s in only.split(",") if s.strip())
            known = {s[0] for s in fac.stations}
            unknown = [s for s in chosen if s not in known]
            twice = sorted({s for s in chosen if chosen.count(s) > 1})
            if len(chosen) < 2 or unknown or twice:
                raise AtlasError(f"--stations = {only!r}: two or more of the facility's "
                                 f"stations ({', '.join(sorted(known))}), each once"
                                 + (f" ({', '.join(twice)} given twice)" if twice else ""))
    workers = local_workers(workers, scheduler)
    serial = serial or workers == 0
    if scheduler:
        check_scheduler(scheduler)
    writable_folder("--out", out)
    with click_errors():
        try:
            doc = atlas(fac, counts, out, serial=serial, scheduler=scheduler,
                        workers=workers or None, progress=_Progress(out), only=chosen,
                        on_cluster=lambda text: click.echo(f"atlas: {text} ...", err=True))
        except KeyboardInterrupt:
            click.echo(f"atlas: the answers so far are kept in {out}; the same command goes "
                       "on from there", err=True)
            raise
    names = [s["name"] for s in doc["stations"]]
    width = max(len(n) for n in names)
    answers = {(p["from"], p["to"]): p["max_trailers"] for p in doc["pairs"]}
    click.echo(f"most trailers from (rows) to (columns), trying {trailers}:")
    click.echo(" " * (width + 2) + " ".join(f"{n[:6]:>6}" for n in names))
    for a in names:
        cells = ["     -" if a == b else f"{answers[(a, b)]:>6}" for b in names]
        click.echo(f"{a:<{width}}  " + " ".join(cells))
    click.echo(f"atlas: {out}")
    sys.stdout.flush()
