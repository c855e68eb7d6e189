"""``pushtrain build-fmu``: build the TrailerTrain FMU."""

from __future__ import annotations

import os
from pathlib import Path

import click

from pushtrain.fmu.variables import MAX_TRAILERS

from ..common import BadInput, click_errors

__all__ = ["build_fmu_cmd"]


def _check_out(out: str) -> None:
    """Raise BadInput unless ``out`` is a file name whose folder exists (or can be made) and
    is writable."""
    if not out.strip():
        raise BadInput(f"--out {out!r}: an empty file name; allowed: a file path such as "
                       "TrailerTrain.fmu")
    folder = Path(out).parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BadInput(f"--out {out}: its folder cannot be created: {exc.strerror or exc}; "
                       "allowed: a file path where folders can be created") from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise BadInput(f"--out {out}: the folder {folder} is not writable")


@click.command("build-fmu")
@click.option("--trailers", "-n", type=click.IntRange(1, MAX_TRAILERS), metavar="N",
              help=f"Number of trailers (1 to {MAX_TRAILERS}); FMI 2.0 only, where it is "
                   "required.")
@click.option("--fmi-version", type=click.Choice(["2", "3"]), default="2", show_default=True,
              help="2: an FMI 2.0 FMU for N trailers; 3: one FMI 3.0 FMU for every N "
                   f"(structural parameter n, 1 to {MAX_TRAILERS}, set before initialization).")
@click.option("--out", "-o", "out", type=click.Path(dir_okay=False), default="TrailerTrain.fmu",
              show_default=True, metavar="FILE", help="Where to write the .fmu.")
@click.option("--force", is_flag=True, help="Rebuild even if cached.")
def build_fmu_cmd(trailers, fmi_version, out, force):
    """Build the TrailerTrain co-simulation FMU: FMI 2.0 for N trailers, or FMI 3.0 for any N.

    \b
    Examples:
      pushtrain build-fmu --trailers 3 -o TrailerTrain.fmu
      pushtrain build-fmu --fmi-version 3 -o TrailerTrain3.fmu
    """
    from pushtrain.fmu.build import build_fmu

    version = int(fmi_version)
    if version == 2 and trailers is None:
        raise BadInput("--trailers N is required for --fmi-version 2 (its n is fixed by the "
                       f"build); allowed: 1 to {MAX_TRAILERS}, or --fmi-version 3 for every n")
    if version == 3 and trailers is not None:
        raise BadInput(f"--trailers {trailers} with --fmi-version 3: the FMI 3.0 FMU serves every "
                       f"n from 1 to {MAX_TRAILERS}; set its structural parameter n when running "
                       "it, and leave --trailers out")
    _check_out(out)
    with click_errors():
        path = build_fmu(trailers, out, fmi_version=version, force=force)
    click.echo(f"{path} (n = {trailers})" if version == 2
               else f"{path} (FMI 3.0, n = 1..{MAX_TRAILERS})")
