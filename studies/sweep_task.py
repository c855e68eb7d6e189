"""The worker side of a sweep: one task co-simulates one run and returns one row of metrics.

:func:`run_task` co-simulates a resolved scenario (its FMU found by :class:`FmuRef`, on this
machine or shipped as bytes); :func:`execute` wraps any task function so that it never raises:
a task that raises becomes a failure row (status ``error``) with NaN metrics
(:func:`failure_row`), a finished co-simulation a row of :func:`metrics_of`. The same functions
run on Dask workers and serially in the client, so both give identical numbers.

Units: lengths [m], times [s], angles in degrees only in ``*_deg`` columns.
"""

from __future__ import annotations

import hashlib
import logging
import math
import pickle
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from pushtrain.files import atomic_write_bytes
from pushtrain.mission.scenario import parse_scenario

from .sweep_spec import METRICS, STATUS_ERROR

__all__ = ["FmuRef", "sha256_of", "run_task", "metrics_of", "failure_row", "execute",
           "execute_batch"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FmuRef:
    """Where a task finds its FMU: ``path`` on this machine, else bytes shipped under ``sha256``."""

    n: int
    path: str
    sha256: str


def sha256_of(path) -> str:
    """SHA-256 (hex) of a file's bytes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _materialize(ref: FmuRef, shared: dict) -> str:
    """The FMU's path on this worker: the client's path if it holds the same file, else the
    shipped bytes written once to a temporary folder."""
    path = Path(ref.path)
    blob = shared.get(f"fmu-{ref.sha256}")
    if path.is_file() and (blob is None or sha256_of(path) == ref.sha256):
        return str(path)
    if blob is None:
        raise FileNotFoundError(f"FMU {ref.path} (n = {ref.n}) is not on this worker and was not "
                                "shipped (use ship_fmu=True for remote clusters)")
    folder = Path(tempfile.gettempdir()) / "pushtrain-sweep-fmu"
    folder.mkdir(parents=True, exist_ok=True)
    target = folder / f"TrailerTrain-n{ref.n}-{ref.sha256[:16]}.fmu"
    if not target.is_file() or sha256_of(target) != ref.sha256:
        atomic_write_bytes(target, blob)
    return str(target)


def run_task(payload: dict, shared: dict):
    """Worker side: co-simulate one resolved scenario (no files written); returns the Result.

    ``payload`` holds ``scenario`` (a resolved, validated scenario dict), ``fmu`` (an
    :class:`FmuRef`) and ``path`` (``PlannedPath.to_dict()`` data for ``plan`` missions, else None).
    """
    from pushtrain.mission.runner import run_scenario

    sc = parse_scenario(payload["scenario"], payload["scenario"].get("name", "<run>"))
    fmu = _materialize(payload["fmu"], shared)
    reference = None
    if sc.mission.kind == "plan":
        from pushtrain.planner.path import PlannedPath

        reference = PlannedPath.from_dict(payload["path"]).to_reference(
            speed=sc.planner.speed, cusp_dwell=sc.planner.cusp_dwell)
    return run_scenario(sc, None, reference=reference, progress=False, fmu=fmu)


def _max_or_nan(values) -> float:
    vals = [v for v in values if v is not None and math.isfinite(v)]
    return max(vals) if vals else math.nan


def metrics_of(result, steady_window: float) -> dict:
    """Every metric of :data:`METRICS` (plus ``status`` and ``message``) from a
    :class:`~pushtrain.cosim.result.Result`.

    ``steady_lat_m`` is the mean lateral error over the last ``steady_window`` seconds of the run
    [m]; NaN when the run is shorter than that.
    """
    s = result.summary
    nan = math.nan
    lat = s.get("lateral_error_m", {})
    head = s.get("heading_error_rad", {})
    slips = s.get("slip", [])
    row = {
        "status": result.status,
        "message": result.message,
        "rms_lat_m": lat.get("rms", nan),
        "max_lat_m": lat.get("max", nan),
        "final_lat_m": lat.get("final", nan),
        "steady_lat_m": nan,
        "rms_heading_deg": math.degrees(head["rms"]) if "rms" in head else nan,
        "max_heading_deg": math.degrees(head["max"]) if "max" in head else nan,
        "max_abs_phi_deg": _max_or_nan(s.get("max_abs_phi_deg", [])),
        "max_F_lat_ratio": _max_or_nan(s.get("max_F_lat_ratio", [])),
        "slip_events": int(sum(e["events"] for e in slips)),
        "slip_time_s": float(sum(e["time_slipping_s"] for e in slips)),
        "t_final": s.get("t_final", nan),
        "steps": s.get("steps", 0),
        "wall_time_s": s.get("wall_time_s", nan),
    }
    data = result.data
    if len(data) and "e_lat" in data.dtype.names:
        t = data["t"]
        if t[-1] - t[0] >= steady_window - 1e-9:
            mask = t >= t[-1] - steady_window - 1e-9
            e_lat = data["e_lat"][mask]
            if np.all(np.isfinite(e_lat)):
                row["steady_lat_m"] = float(np.mean(e_lat))
    return row


def failure_row(status: str, message: str) -> dict:
    """The metric part of a row for a run that produced no result: every metric NaN (unknown,
    not zero: a run that never ran had no slip events and took no steps we could count)."""
    row = {name: math.nan for name in METRICS}
    row.update(status=status, message=message)
    return row


def execute(task_fn: Callable, index: int, key: str, payload, shared,
            steady_window: float) -> dict:
    """Worker side: run ``task_fn(payload, shared)`` and return its row; never raise (an
    exception becomes a failure row with status ``error``)."""
    t0 = time.perf_counter()
    try:
        row = metrics_of(task_fn(payload, shared), steady_window)
    except Exception as exc:  # any failure of one run is recorded, not fatal to the sweep
        log.info("run %d (%s) failed: %s: %s", index, key, type(exc).__name__, exc)
        row = failure_row(STATUS_ERROR, f"{type(exc).__name__}: {exc}")
    row["task_time_s"] = time.perf_counter() - t0
    row["index"], row["key"] = index, key
    return row


def execute_batch(task_fn: Callable, packed: bytes, shared, steady_window: float) -> list[dict]:
    """Worker side: :func:`execute` for each ``(index, key, payload)`` of the pickled list
    ``packed`` in turn, their rows in that order (one Dask task for several short runs; pickled
    by the client so that Dask does not walk every payload looking for futures)."""
    return [execute(task_fn, index, key, payload, shared, steady_window)
            for index, key, payload in pickle.loads(packed)]

