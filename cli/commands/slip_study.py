"""``pushtrain slip-study``: the pure-rotation slip study (Fig. 16-18)."""

from __future__ import annotations

import math
import sys

import click

from ..common import BadInput, out_dir_option
from ..rundir import run_folder

__all__ = ["slip_study_cmd"]


_MAX_TRAILERS = 50  # SlipStudyConfig's range of n


def _bad(option: str, text: str, allowed: str) -> BadInput:
    return BadInput(f"{option} = {text!r}: {allowed}")


def _trailer_list(text: str) -> tuple[int, ...]:
    """``--trailers``: ``'1-3,7'`` -> ``(1, 2, 3, 7)``; each number 1..50, checked before a
    range is expanded (``1-1000000000`` is refused, not listed)."""
    allowed = (f"a comma-separated list of trailer counts 1..{_MAX_TRAILERS} and ranges "
               "LOW-HIGH, e.g. '1-10' or '1,3,7'")
    out = []
    for part in text.split(","):
        ends = part.split("-", 1)
        try:
            numbers = [int(e.strip()) for e in ends]
        except ValueError:
            raise _bad("--trailers", text, f"{allowed}; {part.strip()!r} is not "
                       f"{'a range of whole numbers' if len(ends) == 2 else 'a whole number'}"
                       ) from None
        if any(not 1 <= k <= _MAX_TRAILERS for k in numbers):
            raise _bad("--trailers", text, f"{allowed}; {part.strip()!r} is outside "
                       f"1..{_MAX_TRAILERS}")
        if len(numbers) == 2 and numbers[0] > numbers[1]:
            raise _bad("--trailers", text, f"{allowed}; {part.strip()!r} is an empty range "
                       "(LOW > HIGH)")
        out += list(range(numbers[0], numbers[-1] + 1))
    return tuple(out)


def _alpha_list(text: str) -> tuple[float, ...]:
    """``--alphas``: ``'5,10,30'`` -> ``(5.0, 10.0, 30.0)``, each finite and > 0."""
    allowed = ("a comma-separated list of angular accelerations in deg/s^2, each a finite "
               "number > 0, e.g. '5,10,30'")
    out = []
    for part in text.split(","):
        try:
            value = float(part)
        except ValueError:
            raise _bad("--alphas", text, f"{allowed}; {part.strip()!r} is not a number") from None
        if not (math.isfinite(value) and value > 0.0):
            raise _bad("--alphas", text, f"{allowed}; {part.strip()!r} is not finite and > 0")
        out.append(value)
    return tuple(out)


def _config(trailers: str, alphas: str, w_max: float, payload: float):
    from pushtrain.studies.slipstudy import SlipStudyConfig

    try:
        return SlipStudyConfig(trailers=_trailer_list(trailers), alphas_deg=_alpha_list(alphas),
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
