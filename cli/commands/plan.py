"""``pushtrain plan``: plan the last trailer's path only."""

from __future__ import annotations

from pathlib import Path

import click

from pushtrain.files import atomic_write

from ..common import (
    BadInput,
    check_map,
    click_errors,
    load_scenario_with_overrides,
    scenario_argument,
)
from ..progress import Phases
from ..runs import describe_path, plan_or_fail, write_path

__all__ = ["plan_cmd"]


def _plot_path(sc, path, png: Path) -> None:
    """Draw the map and the planned path of the last trailer into ``png``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pushtrain.mission.runner import world_of

    fig, ax = plt.subplots(figsize=(8, 6))
    try:
        world_of(sc).plot(ax)
        ax.plot(path.poses[:, 0], path.poses[:, 1], "-", color="tab:blue",
                label="planned path (last trailer)")
        ax.plot(*path.poses[0, :2], "go", label="start")
        ax.plot(*path.poses[-1, :2], "r*", markersize=12, label="goal")
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.legend(loc="best")
        ax.set_title(f"{sc.name}: {path.length:.2f} m, {path.n_cusps} cusp(s)")
        fig.tight_layout()
        atomic_write(png, lambda partial: fig.savefig(partial, dpi=120), keep_suffix=True)
    finally:
        plt.close(fig)


def _check_target(option: str, target: str) -> None:
    """Before planning: ``target`` is a file that may be written (new, or a regular file that
    is replaced; never a folder, a device or a FIFO), its folder made as plan-and-run does."""
    import os
    import stat
    import tempfile

    from pushtrain.validation import clip_text

    shown = clip_text(target, 120)
    path = Path(target)
    allowed = "allowed: a new file, or a regular file (replaced), in a folder that can be written"
    try:
        mode = path.stat().st_mode if path.exists() or path.is_symlink() else None
        if mode is not None and not stat.S_ISREG(mode):
            kind = "a folder" if stat.S_ISDIR(mode) else "not a regular file (a device, a FIFO)"
            raise BadInput(f"{option} {shown}: is {kind}; {allowed}")
        folder = path.parent
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder, prefix=".pushtrain-probe-"):
            pass
        if len(os.fsencode(path.name)) > 255 - 40:  # the partial file's name is longer
            raise OSError(36, "File name too long")
    except OSError as exc:
        raise BadInput(f"{option} {shown}: cannot be written: {exc.strerror or exc}; "
                       f"{allowed}") from None


def _written(option: str, target: str, write) -> None:
    try:
        write(Path(target))
    except OSError as exc:
        raise BadInput(f"{option} {target}: cannot be written: {exc.strerror or exc}; allowed: "
                       "a file path in an existing, writable folder") from None


@click.command("plan")
@scenario_argument
@click.option("--out", "-o", "out", type=click.Path(dir_okay=False), metavar="FILE",
              help="Write the path as JSON (default: print a description only).")
@click.option("--seed", type=click.IntRange(min=1), metavar="S", help="Override the scenario seed.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), metavar="PNG",
              help="Draw the map and the planned path.")
def plan_cmd(scenario, out, seed, plot_path):
    """Plan the last trailer's path only (no co-simulation).

    \b
    Example:
      pushtrain plan examples/bay.toml --out bay_path.json --plot bay_path.png
    """
    for option, value in (("--out", out), ("--plot", plot_path)):
        if value is not None and not value.strip():
            raise BadInput(f"{option} {value!r}: an empty file name; allowed: a file path, or "
                           f"no {option}")
    sc = load_scenario_with_overrides(scenario, seed=seed)
    if sc.mission.kind != "plan":
        raise BadInput(f"{scenario}: mission.kind = {sc.mission.kind!r}: 'plan' needs "
                       "mission.kind = 'plan'")
    check_map(sc)
    for option, value in (("--out", out), ("--plot", plot_path)):
        if value is not None:
            _check_target(option, value)
    phases = Phases()
    with click_errors():
        path = plan_or_fail(sc, None, phases)
    phases.done()
    click.echo(describe_path(path))
    if out:
        _written("--out", out, lambda target: write_path(path, target))
        click.echo(f"path: {out}")
    if plot_path:
        _written("--plot", plot_path, lambda target: _plot_path(sc, path, target))
        click.echo(f"plot: {plot_path}")
