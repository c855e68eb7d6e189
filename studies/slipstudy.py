"""Slip study: peak lateral wheel forces of the pure-rotation manoeuvre
(paper Sec. 4.4, Fig. 16-18).

The robot turns on the spot with a trapezoidal yaw rate (:class:`~pushtrain.core.openloop.
RotationProfile`: ramp with angular acceleration alpha to w_max, ramp back); the TrailerTrain FMU
(``slip_mode`` 0: the paper's quasi-static estimate) reports every trailer's lateral force. Three
sweeps, each a row of the result table:

* ``trailers``: number of trailers n (Fig. 16),
* ``alpha``: the robot's angular acceleration (Fig. 17),
* ``payload``: a payload on trailer i = 1..n (Fig. 18).

Each run records the peak |F_lat,i| and the friction limit mu (m_i + payload_i) g of every trailer.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pushtrain.core.openloop import RotationProfile
from pushtrain.cosim.master import simulate
from pushtrain.cosim.plant import InitialState, PlantConfig
from pushtrain.files import atomic_write
from pushtrain.table1 import SAMPLING_TIME

__all__ = ["SlipStudyConfig", "SlipRow", "run_slip_study", "plot_slip_study", "write_csv"]


@dataclass(frozen=True)
class SlipStudyConfig:
    """What to sweep. Angles in degrees at this boundary (converted inside)."""

    trailers: tuple[int, ...] = (1, 2, 3, 4, 5, 6, 7, 8, 9, 10)
    alphas_deg: tuple[float, ...] = (5.0, 10.0, 15.0, 20.0, 30.0, 40.0, 50.0)
    w_max_deg: float = 10.0       # one swing turns the robot by w_max^2 / alpha
    alpha_deg: float = 5.0        # used by the trailers and payload sweeps
    n_for_alpha: int = 3          # trailers in the alpha sweep
    n_for_payload: int = 3        # trailers in the payload sweep
    payload: float = 80.0         # kg, placed on one trailer at a time
    step: float = SAMPLING_TIME

    def __post_init__(self):
        if not self.trailers or any(not 1 <= n <= 50 for n in self.trailers):
            raise ValueError(f"trailers = {self.trailers!r}: each must be 1..50")
        if any(not (a > 0 and math.isfinite(a)) for a in self.alphas_deg) or not self.alphas_deg:
            raise ValueError(f"alphas_deg = {self.alphas_deg!r}: each must be finite and > 0")
        for name in ("w_max_deg", "alpha_deg", "step"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} = {value!r}: must be finite and > 0")
        if not (self.payload >= 0 and math.isfinite(self.payload)):
            raise ValueError(f"payload = {self.payload!r} kg: must be finite and >= 0")


@dataclass(frozen=True)
class SlipRow:
    sweep: str          # "trailers", "alpha" or "payload"
    n: int
    alpha_deg: float
    payload_on: int     # trailer carrying the payload (0: none)
    peak: tuple         # peak |F_lat,i| [N], i = 1..n
    limit: tuple        # mu (m_i + payload_i) g [N]

    @property
    def ratio(self) -> tuple:
        return tuple(p / lim for p, lim in zip(self.peak, self.limit, strict=True))


def _one(fmu_for, n: int, alpha_deg: float, cfg: SlipStudyConfig, payload_on: int = 0) -> tuple:
    profile = RotationProfile(n, math.radians(cfg.w_max_deg), math.radians(alpha_deg))
    payload = np.zeros(n)
    if payload_on:
        payload[payload_on - 1] = cfg.payload
    horizon = cfg.step * math.ceil(profile.half_period / cfg.step)  # one full swing
    plant = PlantConfig(n, payload=payload, robot_alpha_max=10.0, slip_mode=0)
    result = simulate(fmu_for(n), None, profile, initial=InitialState(0.0, 0.0, np.zeros(n + 1)),
                      plant=plant, step=cfg.step, horizon=horizon)
    d = result.data
    peak = tuple(float(np.max(np.abs(d[f"F_lat{i}"]))) for i in range(1, n + 1))
    limit = tuple(float(d[f"F_lat_max{i}"][0]) for i in range(1, n + 1))
    return peak, limit


def run_slip_study(cfg: SlipStudyConfig, fmu_for=None, progress=None) -> list[SlipRow]:
    """Run the three sweeps; ``fmu_for(n)`` gives the FMU path (default: build_fmu)."""
    if fmu_for is None:
        from pushtrain.fmu.build import build_fmu as fmu_for
    jobs = [("trailers", n, cfg.alpha_deg, 0) for n in cfg.trailers]
    jobs += [("alpha", cfg.n_for_alpha, a, 0) for a in cfg.alphas_deg]
    jobs += [
        ("payload", cfg.n_for_payload, cfg.alpha_deg, i) for i in range(1, cfg.n_for_payload + 1)
    ]
    rows = []
    for k, (sweep, n, alpha, on) in enumerate(jobs):
        peak, limit = _one(fmu_for, n, alpha, cfg, on)
        rows.append(SlipRow(sweep, n, alpha, on, peak, limit))
        if progress is not None:
            progress(k + 1, len(jobs))
    return rows


def write_csv(rows: list[SlipRow], path) -> Path:
    """One line per run and trailer; written atomically."""
    def write(partial: Path) -> None:
        with open(partial, "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(["sweep", "n", "alpha_deg", "payload_on", "trailer", "peak_F_lat_N",
                             "limit_N", "ratio"])
            for row in rows:
                for i, (p, lim) in enumerate(zip(row.peak, row.limit, strict=True), start=1):
                    writer.writerow([row.sweep, row.n, row.alpha_deg, row.payload_on, i,
                                     f"{p:.6g}", f"{lim:.6g}", f"{p / lim:.6g}"])

    return atomic_write(path, write)


def plot_slip_study(rows: list[SlipRow], path) -> Path:
    """Three panels like the paper's Fig. 16-18: peak |F_lat,1| (and the largest over trailers)
    against n, alpha and the payload position, with the friction limit."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(13, 4.2))
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 3)
    for ax, sweep, xlabel, title in (
        (axes[0], "trailers", "number of trailers n", "Peak lateral force vs n (Fig. 16)"),
        (axes[1], "alpha", "robot angular acceleration alpha [deg/s$^2$]",
         "vs angular acceleration (Fig. 17)"),
        (axes[2], "payload", "trailer carrying the payload", "vs payload position (Fig. 18)"),
    ):
        sel = [r for r in rows if r.sweep == sweep]
        if not sel:
            ax.set_visible(False)
            continue
        x = [
            r.n if sweep == "trailers" else r.alpha_deg if sweep == "alpha" else r.payload_on
            for r in sel
        ]
        ax.plot(x, [r.peak[0] for r in sel], "o-", color="tab:blue",
                label="trailer 1: peak |F_lat,1|")
        ax.plot(x, [max(r.peak) for r in sel], "s--", color="tab:orange", ms=4,
                label="largest over all trailers")
        ax.plot(x, [r.limit[0] for r in sel], "k:", label="friction limit of trailer 1")
        over = [xi for xi, r in zip(x, sel, strict=True) if r.peak[0] > r.limit[0]]
        if over:
            ax.axvspan(min(over) - 0.5 if sweep != "alpha" else min(over), max(x), color="tab:red",
                       alpha=0.08, label="trailer 1 slides")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("lateral wheel force [N]")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
        if sweep != "alpha":
            ax.set_xticks(sorted(set(x)))
        ax.legend(fontsize=7, loc="upper right" if sweep == "payload" else "lower right")
    fig.suptitle(
        "Pure robot rotation: lateral wheel forces against friction (slip_mode 0 estimate)"
    )
    fig.tight_layout()
    return atomic_write(path, lambda partial: fig.savefig(partial, dpi=120), keep_suffix=True)
