"""What the ROS 2 export reads from a run folder (:func:`read_run`): the resolved scenario, the
results table, the summary and the planned path (or, for a failed plan, the partial one)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pushtrain.cosim.result import RESULTS_CSV, RESULTS_NPZ, SUMMARY_JSON, load_results
from pushtrain.errors import InputError, PushtrainError
from pushtrain.mission.scenario import Scenario, parse_scenario
from pushtrain.planner.path import PlannedPath

__all__ = ["RunFolder", "read_run", "required_columns", "SCENARIO_JSON", "PATH_JSON",
           "PARTIAL_PATH_JSON", "PLANNING_FAILED"]

SCENARIO_JSON = "scenario.json"
"""The resolved scenario of a run (every default filled in)."""
PATH_JSON = "path.json"
"""The planned path of a ``plan`` mission."""
PARTIAL_PATH_JSON = "partial_path.json"
"""The closest the planner came, written beside ``summary.json`` when planning failed: a
``pushtrain.planned_path`` document with ``info.partial`` true."""
PLANNING_FAILED = "planning_failed"
"""``summary.json`` status of a run whose plan was not found (no motion, no results)."""


@dataclass(frozen=True, eq=False)
class RunFolder:
    """One run folder, read.

    Attributes
    ----------
    folder : Path
    scenario : Scenario
        The resolved scenario (``scenario.json``).
    summary : dict
        ``summary.json`` ({} when the folder has none).
    data : structured ndarray or None
        The results table (one row per communication point); None for a failed plan.
    path : PlannedPath or None
        ``path.json``, or for a failed plan ``partial_path.json`` when the planner left one.
    partial : bool
        Whether ``path`` is a failed plan's partial path.
    """

    folder: Path
    scenario: Scenario
    summary: dict
    data: np.ndarray | None
    path: PlannedPath | None
    partial: bool

    @property
    def planning_failed(self) -> bool:
        """Whether the run stopped because no plan was found."""
        return self.summary.get("status") == PLANNING_FAILED

    @property
    def n(self) -> int:
        """Number of trailers."""
        return self.scenario.train.n


def _json(file: Path, what: str):
    try:
        return json.loads(file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{file}: cannot be read as {what} ({exc}); allowed: the file as "
                         "plan-and-run or run wrote it") from None


def _planned_path(file: Path) -> PlannedPath:
    try:
        return PlannedPath.from_dict(_json(file, "a planned path"))
    except (PushtrainError, KeyError, TypeError, ValueError) as exc:
        raise InputError(f"{file}: not a planned path ({exc}); allowed: the file as "
                         "plan-and-run wrote it") from None


def required_columns(n: int) -> list[str]:
    """The results columns the export reads, for ``n`` trailers."""
    bodies = [f"{q}{i}" for q in ("x", "y", "theta") for i in range(n + 1)]
    joints = [f"{q}{i}" for q in ("phi", "phi_meas") for i in range(1, n + 1)]
    return ["t", *bodies, *joints, "v_cmd", "w_cmd", "x_d", "y_d", "theta_d", "e_lon", "e_lat",
            "e_theta"]


def read_run(run_dir) -> RunFolder:
    """Read the run folder ``run_dir`` (written by ``plan-and-run`` or ``run``).

    Raises
    ------
    InputError
        ``run_dir`` is not a folder, or lacks ``scenario.json``, or lacks ``results.npz`` (and
        ``results.csv``) without being a failed plan; or one of its files cannot be read. The
        message names the file.
    """
    folder = Path(run_dir)
    if not folder.is_dir():
        raise InputError(f"RUN_DIR = {str(run_dir)!r} is not a folder; allowed: a run folder "
                         "written by plan-and-run or run")
    scenario_file = folder / SCENARIO_JSON
    if not scenario_file.is_file():
        raise InputError(f"RUN_DIR = {str(run_dir)!r} has no {SCENARIO_JSON}: not a run folder; "
                         "allowed: a folder written by plan-and-run or run")
    summary_file = folder / SUMMARY_JSON
    summary = _json(summary_file, "a run summary") if summary_file.is_file() else {}
    if not isinstance(summary, dict):
        raise InputError(f"{summary_file}: holds {type(summary).__name__}, not a JSON object; "
                         "allowed: the file as plan-and-run or run wrote it")
    failed = summary.get("status") == PLANNING_FAILED
    data = None
    if not failed:
        if not ((folder / RESULTS_NPZ).is_file() or (folder / RESULTS_CSV).is_file()):
            raise InputError(f"RUN_DIR = {str(run_dir)!r} has no {RESULTS_NPZ}: not a finished "
                             "run (its summary.json does not say planning_failed either); "
                             "allowed: a folder written by plan-and-run or run")
        try:
            data = load_results(folder)
        except (OSError, ValueError, KeyError) as exc:
            raise InputError(f"{folder / RESULTS_NPZ}: cannot be read ({exc}); allowed: the "
                             "file as plan-and-run or run wrote it") from None
        if len(data) == 0 or "t" not in data.dtype.names:
            raise InputError(f"{folder / RESULTS_NPZ}: holds no samples; allowed: the table of "
                             "a run")
    scenario = parse_scenario(_json(scenario_file, "a scenario"), str(scenario_file))
    if data is not None:
        missing = [c for c in required_columns(scenario.train.n) if c not in data.dtype.names]
        if missing:
            raise InputError(f"{folder / RESULTS_NPZ}: has no column {', '.join(missing[:5])}"
                             f"{' ...' if len(missing) > 5 else ''} for the "
                             f"{scenario.train.n} trailers of its scenario.json; allowed: the "
                             "table of this run")
    path_file = folder / (PARTIAL_PATH_JSON if failed else PATH_JSON)
    path = _planned_path(path_file) if path_file.is_file() else None
    return RunFolder(folder, scenario, summary, data, path, failed and path is not None)
