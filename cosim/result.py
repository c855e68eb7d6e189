"""What :func:`~pushtrain.cosim.master.simulate` returns: the run's status, its table of results,
its summary (:func:`summarize`), and the files :meth:`Result.save` writes (each atomically)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pushtrain.files import atomic_write

__all__ = ["Result", "summarize", "STATUS_GOAL", "STATUS_NOT_REACHED", "STATUS_JACKKNIFE",
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

    def save(self, out_dir) -> dict:
        """Write ``results.csv``, ``results.npz`` and ``summary.json`` into ``out_dir``."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        names = self.data.dtype.names
        csv_path = out / "results.csv"
        _atomic_write(csv_path, lambda f: _write_csv(f, self.data), binary=False)
        npz_path = out / "results.npz"
        _atomic_write(npz_path,
                      lambda f: np.savez_compressed(f, **{k: self.data[k] for k in names}))
        summary_path = out / "summary.json"
        _atomic_write(summary_path, lambda f: json.dump(self.summary, f, indent=2), binary=False)
        self.files = {"csv": str(csv_path), "npz": str(npz_path), "summary": str(summary_path)}
        return self.files


def _write_csv(f, data: np.ndarray) -> None:
    names = data.dtype.names
    f.write(",".join(names) + "\n")
    columns = np.column_stack([data[k].astype(float) for k in names])
    np.savetxt(f, columns, delimiter=",", fmt="%.10g")


def _atomic_write(path: Path, writer, binary: bool = True) -> None:
    """``writer(f)`` on an open file, written atomically over ``path``."""
    def write(partial: Path) -> None:
        with open(partial, "wb" if binary else "w") as f:
            writer(f)

    atomic_write(path, write)


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
