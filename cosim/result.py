"""What :func:`~pushtrain.cosim.master.simulate` returns: the run's status, its table of results,
its summary (:func:`summarize`), and the one home of a run folder's result files:
:meth:`Result.save` writes them (each atomically), :func:`load_results` reads the table back."""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pushtrain.files import atomic_write, atomic_write_text

__all__ = ["Result", "summarize", "load_results", "write_npz", "write_csv", "RESULTS_NPZ",
           "RESULTS_CSV", "SUMMARY_JSON", "NPZ_LEVEL", "STATUS_GOAL", "STATUS_NOT_REACHED",
           "STATUS_JACKKNIFE",
           "STATUS_FMU_ERROR", "STATUS_TIME_LIMIT", "STATUS_COMPLETED"]

STATUS_GOAL = "goal_reached"
STATUS_NOT_REACHED = "goal_not_reached"
STATUS_JACKKNIFE = "jackknifed"
STATUS_FMU_ERROR = "fmu_error"
STATUS_TIME_LIMIT = "time_limit"
STATUS_COMPLETED = "completed"  # fixed-horizon run without a goal check


@dataclass
class Result:
    """Outcome of :func:`simulate`."""

    status: str
    message: str
    data: np.ndarray  # structured array, one row per communication point
    summary: dict
    n_trailers: int
    fmu_log: str = ""
    files: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status in (STATUS_GOAL, STATUS_COMPLETED)

    def save(self, out_dir, *, csv: bool = False) -> dict:
        """Write the run folder's result files into ``out_dir``: ``results.npz`` (the table),
        ``summary.json`` and, with ``csv``, ``results.csv``; each atomically. Returns {kind:
        path} of the files written (also set as :attr:`files`)."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        files = {"npz": out / RESULTS_NPZ}
        atomic_write(files["npz"], lambda partial: write_npz(partial, self.data))
        if csv:
            files["csv"] = out / RESULTS_CSV
            atomic_write(files["csv"], lambda partial: write_csv(partial, self.data))
        files["summary"] = out / SUMMARY_JSON
        atomic_write_text(files["summary"], json.dumps(self.summary, indent=2))
        self.files = {kind: str(path) for kind, path in files.items()}
        return self.files


# ------------------------------------------------------------------------------ result files
RESULTS_NPZ = "results.npz"
"""The main table of a run folder: one float64 array per column (``np.load``), exact."""
RESULTS_CSV = "results.csv"
"""The same table as text (10 significant digits), written only on request."""
SUMMARY_JSON = "summary.json"
"""The run's summary (:func:`summarize`)."""

NPZ_LEVEL = 1
"""Deflate level of ``results.npz``: level 1 writes it in half the time of NumPy's default (6)
for the same size (float64 samples hardly compress further: 5.54 against 5.55 MB for
l_corridor)."""


def write_npz(path: Path, data: np.ndarray) -> None:
    """``data``'s columns into a compressed ``.npz`` at ``path`` (the layout of
    ``np.savez_compressed``: one ``NAME.npy`` member per column, in order)."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=NPZ_LEVEL) as zf:
        for name in data.dtype.names:
            with zf.open(f"{name}.npy", "w", force_zip64=True) as f:
                np.lib.format.write_array(f, np.ascontiguousarray(data[name]),
                                          allow_pickle=False)


def write_csv(path: Path, data: np.ndarray) -> None:
    """``data``'s columns as CSV text at ``path`` (a header of names, 10 significant digits)."""
    names = data.dtype.names
    with open(path, "w", encoding="utf-8") as f:
        f.write(",".join(names) + "\n")
        np.savetxt(f, np.column_stack([data[k].astype(float) for k in names]), delimiter=",",
                   fmt="%.10g")


def load_results(run_dir) -> np.ndarray:
    """The table of a run folder as a structured float64 array (columns as recorded).

    Reads ``results.npz``; a folder that has only ``results.csv`` (written by hand or trimmed)
    is read from the CSV. Raises FileNotFoundError when the folder has neither.
    """
    folder = Path(run_dir)
    npz, csv = folder / RESULTS_NPZ, folder / RESULTS_CSV
    if npz.is_file():
        with np.load(npz) as z:
            names = list(z.files)
            columns = [z[name] for name in names]
    elif csv.is_file():
        table = np.genfromtxt(csv, delimiter=",", names=True, dtype=float, ndmin=1)
        names = list(table.dtype.names)
        columns = [table[name] for name in names]
    else:
        raise FileNotFoundError(f"{folder}: no {RESULTS_NPZ} or {RESULTS_CSV} in it")
    data = np.empty(len(columns[0]) if columns else 0, dtype=[(k, "f8") for k in names])
    for name, column in zip(names, columns, strict=True):
        data[name] = column
    return data


def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a**2))) if a.size else float("nan")


def summarize(data, n: int, status: str, message: str, wall: float, step: float) -> dict:
    """The ``summary.json`` of a run: status and message, tracking errors of the last trailer
    (rms, max, final), the largest joint angles [deg], lateral forces against their friction
    limit, slip events per trailer, and the speed of the run (``wall`` [s], ``step`` [s])."""
    summary = {"status": status, "message": message, "n_trailers": n, "step": step,
               "steps": max(len(data) - 1, 0), "wall_time_s": round(wall, 4)}
    if len(data) == 0:
        return summary
    e_lat, e_th = data["e_lat"], data["e_theta"]
    summary.update(
        t_final=float(data["t"][-1]),
        lateral_error_m={"rms": _rms(e_lat), "max": float(np.max(np.abs(e_lat))),
                         "final": float(e_lat[-1])},
        heading_error_rad={"rms": _rms(e_th), "max": float(np.max(np.abs(e_th))),
                           "final": float(e_th[-1])},
        longitudinal_error_m={"rms": _rms(data["e_lon"]), "final": float(data["e_lon"][-1])},
        max_abs_phi_deg=[float(np.degrees(np.max(np.abs(data[f"phi{i}"]))))
                         for i in range(1, n + 1)],
        steps_per_second=round((len(data) - 1) / wall, 1) if wall > 0 else None,
    )
    ratios, slips = [], []
    for i in range(1, n + 1):
        f = np.abs(data[f"F_lat{i}"])
        ratios.append(float(np.max(f) / data[f"F_lat_max{i}"][0])
                      if data[f"F_lat_max{i}"][0] > 0 else None)
        flag = data[f"slipping{i}"] > 0.5
        rising = np.flatnonzero(flag[1:] & ~flag[:-1]) + 1
        starts = ([0] if flag[0] else []) + rising.tolist()
        slips.append({"trailer": i, "events": len(starts),
                      "first_t": float(data["t"][starts[0]]) if starts else None,
                      "time_slipping_s": float(np.count_nonzero(flag) * step)})
    summary["max_F_lat_ratio"] = ratios
    summary["slip"] = slips
    return summary
