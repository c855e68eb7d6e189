"""``pushtrain export-bag``: a run folder as a rosbag2 folder for ROS 2 tools and Foxglove."""

from __future__ import annotations

import logging
from contextlib import contextmanager
from pathlib import Path

import click

from ..common import BadInput, click_errors

__all__ = ["export_bag_cmd", "write_bag", "bag_after_run", "BAG_FOLDER"]

log = logging.getLogger(__name__)

BAG_FOLDER = "bag"
"""The bag's folder inside a run folder (``plan-and-run --bag``)."""


def write_bag(run_dir, out, epoch: float | None = None, rate: float | None = None):
    """Export ``run_dir`` to the bag folder ``out`` (:func:`pushtrain.ros.bag.export_bag`);
    pushtrain's errors become click exceptions (bad input: exit 2)."""
    from pushtrain.ros.bag import EPOCH_S, export_bag

    if not str(out).strip():
        raise BadInput(f"--out {str(out)!r}: an empty folder name; allowed: a folder path")
    with click_errors():
        return export_bag(run_dir, out, epoch_s=EPOCH_S if epoch is None else epoch,
                          rate_hz=rate)


def _echo(done) -> None:
    total = sum(done.counts.values())
    click.echo(f"bag: {done.folder} ({total} messages on {len(done.counts)} topics, "
               f"{done.mcap.stat().st_size / 1e6:.1f} MB)")


class _BagTarget:
    folder: Path | None = None


@contextmanager
def bag_after_run(enabled: bool):
    """``plan-and-run --bag``: around the run folder's block, write the folder set as
    ``.folder`` as the bag ``<folder>/bag`` once the run has ended (its ``summary.json``
    written). After a failure (no plan found, a picture not drawn) the bag is written when the
    folder holds a failed plan or the results, and the run's own error is the one reported."""
    target = _BagTarget()
    try:
        yield target
    except click.ClickException:
        if enabled and target.folder is not None:
            try:
                _echo(write_bag(target.folder, Path(target.folder) / BAG_FOLDER))
            except click.ClickException as exc:
                log.info("no bag of %s: %s", target.folder, exc.format_message())
        raise
    if enabled and target.folder is not None:
        _echo(write_bag(target.folder, Path(target.folder) / BAG_FOLDER))


@click.command("export-bag", short_help="Write a run folder as a rosbag2 (MCAP) folder.")
@click.argument("run_dir", type=click.Path(file_okay=True, dir_okay=True))
@click.option("--out", "-o", "out", required=True, type=click.Path(), metavar="BAG_DIR",
              help="The bag folder: new, empty or an earlier bag (replaced when the new one is "
                   "complete); nothing else is replaced.")
@click.option("--epoch", type=click.FloatRange(min=0.0), default=None, metavar="SECONDS",
              help="Unix time [s] of simulated time zero (default 946684800: "
                   "2000-01-01T00:00:00Z).")
@click.option("--rate", type=click.FloatRange(min=10.0), default=None, metavar="HZ",
              help="Write every k-th sample, at least HZ (>= 10); default: every recorded "
                   "sample.")
def export_bag_cmd(run_dir, out, epoch, rate):
    """Write RUN_DIR (a folder of plan-and-run or run) as a rosbag2 folder: metadata.yaml and
    one MCAP file of standard ROS 2 messages (/map, /plan, /reference, /goal, /tf,
    /joint_states, /joint_states/measured, /train_markers, /cmd_vel, /tracking_error,
    /summary) that ros2 bag, RViz and Foxglove open. A failed plan gives the map, the
    partial plan, the goal and the summary.

    \b
    Example:
      pushtrain export-bag runs/l --out runs/l/bag
      ros2 bag info runs/l/bag
    """
    _echo(write_bag(run_dir, out, epoch, rate))
