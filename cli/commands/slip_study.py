"""``pushtrain slip-study``: the pure-rotation slip study (Fig. 16-18)."""

from __future__ import annotations

import sys

import click

from ..common import BadInput, out_dir_option
from ..rundir import run_folder


def _int_list(text: str) -> tuple[int, ...]:
    """``'1-3,7'`` -> ``(1, 2, 3, 7)``."""
    out = []
    for part in text.split(","):
        if "-" in part:
            lo, hi = part.split("-", 1)
            out += list(range(int(lo), int(hi) + 1))
        else:
            out.append(int(part))
    return tuple(out)


def _config(trailers: str, alphas: str, w_max: float, payload: float):
    from pushtrain.studies.slipstudy import SlipStudyConfig

    try:
        return SlipStudyConfig(trailers=_int_list(trailers),
                               alphas_deg=tuple(float(a) for a in alphas.split(",")),
                               w_max_deg=w_max, payload=payload)
    except ValueError as exc:
        raise BadInput(f"slip-study: {exc}") from None


def _print_table(rows) -> None:
    sweeps = (("trailers", "n"), ("alpha", "alpha [deg/s^2]"), ("payload", "payload on"))
    for sweep, label in sweeps:
        click.echo(f"{label:>16} | peak |F_lat,1| [N] | limit [N] | slides")
        for r in (r for r in rows if r.sweep == sweep):
            key = r.n if sweep == "trailers" else r.alpha_deg if sweep == "alpha" else r.payload_on
            click.echo(f"{key:>16} | {r.peak[0]:18.2f} | {r.limit[0]:9.2f} | "
                       f"{'yes' if r.peak[0] > r.limit[0] else 'no'}")


@click.command("slip-study")
@click.option("--trailers", default="1-10", show_default=True, metavar="LIST",
              help="Numbers of trailers for the n sweep, e.g. '1-10' or '1,3,7'.")
@click.option("--alphas", default="5,10,15,20,30,40,50", show_default=True, metavar="LIST",
              help="Robot angular accelerations [deg/s^2] for the alpha sweep.")
@click.option("--w-max", "w_max", type=click.FloatRange(min=0, min_open=True), default=10.0,
              show_default=True, metavar="DEG_S", help="Peak yaw rate of the rotation [deg/s].")
@click.option("--payload", type=click.FloatRange(min=0), default=80.0, show_default=True,
              metavar="KG", help="Payload placed on one trailer at a time (payload sweep).")
@out_dir_option
def slip_study_cmd(trailers, alphas, w_max, payload, out):
    """Pure-rotation slip study: peak lateral wheel forces against friction (Fig. 16-18).

    Sweeps the number of trailers, the robot's angular acceleration and the payload position
    with the FMU and writes slip_study.csv and slip_study.png.

    \b
    Example:
      pushtrain slip-study --trailers 1-10 --alphas 5,15,30,50 --out runs/slip
    """
    from pushtrain.studies.slipstudy import plot_slip_study, run_slip_study, write_csv

    cfg = _config(trailers, alphas, w_max, payload)
    with run_folder(out, "slip-study") as out_dir:
        with click.progressbar(length=len(cfg.trailers) + len(cfg.alphas_deg) + cfg.n_for_payload,
                               label="slip study", file=sys.stderr) as bar:
            rows = run_slip_study(cfg, progress=lambda done, total: bar.update(1))
        write_csv(rows, out_dir / "slip_study.csv")
        plot_slip_study(rows, out_dir / "slip_study.png")
    _print_table(rows)
    click.echo(f"results: {out_dir}")
