"""Figures and an animation of a co-simulation run (matplotlib with the Agg canvas, no pyplot).

Every function takes the structured array ``data`` of :attr:`pushtrain.cosim.result.Result.data`
(a run folder's table, :func:`pushtrain.cosim.result.load_results`) and the number of trailers
``n``. :func:`plot_all` writes the standard set into a folder and :func:`plot_file` one file
of it by name; each file is written atomically (a temporary file in the same folder, then
``os.replace``).

The figures live by concern, each imported from its own module: :mod:`~pushtrain.report.mapview`
(top view: ``plot_map``, ``map_figure``), :mod:`~pushtrain.report.timeseries` (inputs, joint
angles, tracking error, lateral forces: ``plot_*`` and ``*_figure``) and
:mod:`~pushtrain.report.animation` (GIF: ``animate``), on shared pieces in
:mod:`~pushtrain.report.common` and :mod:`~pushtrain.report.geometry`.

Conventions as in :mod:`pushtrain.core.kinematics`: positions are the robot centre (body 0) and
the trailers' axle midpoints [m], headings point toward the robot [rad]. Plots show angles in
degrees, lateral and longitudinal errors in centimetres. Bad arguments raise
:class:`~pushtrain.errors.PlotError`.
"""

from __future__ import annotations

import gc
import logging
import time as _time
import warnings
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from pushtrain.errors import PlotError
from pushtrain.report import GIF_FILE, HTML_FILE, PNG_FILES
from pushtrain.report.animation import animate
from pushtrain.report.common import add_note, nothing_to_draw, save
from pushtrain.report.data import check_data, check_n, drawable, finite_note, pose_columns
from pushtrain.report.mapview import map_figure
from pushtrain.report.timeseries import (
    inputs_and_joints_figure,
    lateral_forces_figure,
    tracking_error_figure,
)

__all__ = ["plot_all", "plot_file"]

log = logging.getLogger(__name__)


def _unwrap(result_or_data, n: int):
    """(data, status or None) of a Result or of its data; the Result's n_trailers must be n."""
    # a numpy array has a .data attribute too (its buffer): only unwrap Result-like objects
    if isinstance(result_or_data, np.ndarray):
        return result_or_data, None
    data = getattr(result_or_data, "data", result_or_data)
    n_result = getattr(result_or_data, "n_trailers", None)
    if n_result is not None and n_result != n:
        raise PlotError(f"n = {n} but the result has n_trailers = {n_result}")
    return data, getattr(result_or_data, "status", None)


@contextmanager
def _collecting():
    """A block in which ``collect()`` frees the figures drawn so far, cheaply.

    A Figure and its artists refer to each other, so a figure no longer used is freed only by
    the cyclic garbage collector, whose full passes are rare: the figures of :func:`plot_all`
    would pile up (30 MiB for four). A full pass over every object costs about 80 ms, so the
    objects that exist when the block starts are frozen (``gc.freeze``, undone at the end) and
    each pass looks at the new ones only. If someone else froze objects already, it is left
    alone and the passes are full ones.
    """
    frozen_here = gc.get_freeze_count() == 0
    if frozen_here:
        gc.freeze()
    try:
        yield gc.collect
    finally:
        if frozen_here:
            gc.unfreeze()


def _title(n: int, status: str | None) -> str | None:
    """The map's title naming the run's status (None without one)."""
    if status is None:
        return None
    return f"Robot with {n} trailer{'s' if n > 1 else ''}: {status.replace('_', ' ')}"


def plot_file(name: str, data, n: int, out_dir, *, world=None, path_xy=None, footprints=None,
              geometry=None, status: str | None = None, summary: dict | None = None,
              phi_max_deg: float | None = None, keep_out: float | None = None) -> Path:
    """Write the standard file ``name`` (one of :data:`PNG_FILES`, :data:`GIF_FILE` or
    :data:`HTML_FILE`) of a run into ``out_dir`` (which must exist) and return its path.

    ``data`` and ``n`` as in :func:`plot_map`; ``world``, ``path_xy``, ``footprints`` and
    ``geometry`` as there (the plots over time ignore them); ``status`` (e.g. ``goal_reached``)
    goes into the map's title. ``summary`` (the run's ``summary.json``), ``phi_max_deg`` (the
    joint limit) and ``keep_out`` (the clearance [m] whose band is drawn) are for the page and
    the joint plot.

    A run that diverged or stopped early may hold NaN or inf: what is finite is drawn and the
    picture says, in red below it, which columns were not (:func:`~pushtrain.report.data.
    finite_note`); the map and the GIF draw the rows whose poses are finite. A table with no
    row to draw gives a picture saying so instead of an error.
    """
    out = Path(out_dir)
    if name == HTML_FILE:
        from pushtrain.report.html import plot_report

        return plot_report(data, n, out / name, world=world, path_xy=path_xy,
                           footprints=footprints, status=status, summary=summary,
                           phi_max_deg=phi_max_deg, keep_out=keep_out)
    if name not in PNG_FILES + (GIF_FILE,):
        raise PlotError(f"file {name!r}: the standard files are "
                        f"{', '.join(PNG_FILES + (GIF_FILE, HTML_FILE))}")
    n = check_n(n)
    if getattr(getattr(data, "dtype", None), "names", None) is None:
        check_data(data, n, ())  # raises PlotError saying what data is instead of a table
    note = finite_note(data)
    if note:
        log.info("%s: %s", name, note)
    poses = name in ("map.png", GIF_FILE)
    shown = drawable(data, pose_columns(n) + ["x_d", "y_d", "theta_d"] if poses else ())
    if len(shown) == 0:
        why = ("the results have no rows" if len(data) == 0 else
               "no row has a finite time" + (" and finite poses" if poses else ""))
        return nothing_to_draw(out / name, f"{name}: nothing to draw: {why}.", note)
    with warnings.catch_warnings(record=True) as caught:  # to run.log, not the terminal
        warnings.simplefilter("always")
        try:
            return _draw_file(name, shown, n, out, note, world=world, path_xy=path_xy,
                              footprints=footprints, geometry=geometry, status=status,
                              phi_max_deg=phi_max_deg)
        finally:
            for w in caught:  # all-NaN columns (said by the note), matplotlib's layout hints
                log.info("%s: %s: %s", name, w.category.__name__, w.message)


def _draw_file(name, shown, n, out, note, *, world, path_xy, footprints, geometry, status,
               phi_max_deg) -> Path:
    """:func:`plot_file`'s drawing of a matplotlib file from the rows ``shown``."""
    if name == GIF_FILE:
        return animate(shown, n, out / name, world=world, footprints=footprints,
                       path_xy=path_xy, geometry=geometry)
    if name == "map.png":
        fig = map_figure(shown, n, world=world, path_xy=path_xy, footprints=footprints,
                         title=_title(n, status), geometry=geometry)
    elif name == "inputs_joints.png":
        fig = inputs_and_joints_figure(shown, n, phi_max_deg)
    elif name == "tracking_error.png":
        fig = tracking_error_figure(shown, n)
    else:
        fig = lateral_forces_figure(shown, n)
    if note:
        add_note(fig, note)
    return save(fig, out / name)


def plot_all(result_or_data, n: int, out_dir, *, world=None, path_xy=None, footprints=None,
             gif: bool = True, geometry=None, phi_max_deg: float | None = None) -> list[Path]:
    """Write ``map.png``, ``inputs_joints.png``, ``tracking_error.png``, ``lateral_forces.png``
    and (if ``gif``) ``train.gif`` into ``out_dir``.

    Parameters
    ----------
    result_or_data : Result or numpy structured array
        A :class:`~pushtrain.cosim.result.Result` (its status goes into the map's title) or its
        ``data``.
    n : int
        Number of trailers (must match ``Result.n_trailers``).
    out_dir : path-like
        Output folder (created if missing).
    world, path_xy, footprints, geometry
        As in :func:`plot_map`.
    gif : bool
        Also write the animation.
    phi_max_deg : float, optional
        The joint limit drawn on the joint angles [deg].

    Returns
    -------
    list of pathlib.Path
        The written files, in the order above.
    """
    n = check_n(n)
    data, status = _unwrap(result_or_data, n)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    start = _time.perf_counter()
    written = []
    with _collecting() as collect:
        for name in PNG_FILES + ((GIF_FILE,) if gif else ()):
            written.append(plot_file(name, data, n, out, world=world, path_xy=path_xy,
                                     footprints=footprints, geometry=geometry, status=status,
                                     phi_max_deg=phi_max_deg))
            collect()
    log.info("wrote %d plot files to %s in %.1f s", len(written), out, _time.perf_counter() - start)
    return written
