"""``pushtrain build-fmu``: build the TrailerTrain FMU."""

from __future__ import annotations

import os
from pathlib import Path

import click

from ..common import MAX_TRAILERS, BadInput, click_errors


def _check_out(out: str) -> None:
    """Raise BadInput unless ``out``'s folder exists (or can be made) and is writable."""
    folder = Path(out).parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BadInput(f"--out {out}: its folder cannot be created: {exc.strerror or exc}; "
                       "allowed: a file path where folders can be created") from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise BadInput(f"--out {out}: the folder {folder} is not writable")


@click.command("build-fmu")
@click.option("--trailers", "-n", type=click.IntRange(1, MAX_TRAILERS), required=True, metavar="N",
              help=f"Number of trailers (1 to {MAX_TRAILERS}).")
@click.option("--out", "-o", "out", type=click.Path(dir_okay=False), default="TrailerTrain.fmu",
              show_default=True, metavar="FILE", help="Where to write the .fmu.")
@click.option("--force", is_flag=True, help="Rebuild even if cached.")
def build_fmu_cmd(trailers, out, force):
    """Build the TrailerTrain FMI 2.0 co-simulation FMU for N trailers.

    \b
    Example:
      pushtrain build-fmu --trailers 3 -o TrailerTrain.fmu
    """
    from pushtrain.fmu import build_fmu

    _check_out(out)
    with click_errors():
        path = build_fmu(trailers, out, force=force)
    click.echo(f"{path} (n = {trailers})")
