"""Report of a robustness sweep: a summary (``report.json``), a text table and plots.

Works on the rows of :func:`pushtrain.studies.sweep.run_sweep` (``results.csv``). For each swept
parameter, :func:`parameter_figure` draws the success rate, the steady and maximum lateral
tracking error, and the peak lateral wheel force against friction (with the 1.0 slip line)
against the parameter's value. When joint biases are swept, :func:`bias_figure` draws the
measured steady offset beside the closed-form prediction of :mod:`pushtrain.core.analysis`
against the effective bias eps_eff = sum (-1)^(n-k) eps_k.

Figures are :class:`matplotlib.figure.Figure` objects on the Agg canvas (no pyplot); files are
written atomically. Offsets are shown in centimetres.
"""

from __future__ import annotations

import json
import logging
import math
import re
from pathlib import Path
from typing import Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from pushtrain.files import atomic_write, atomic_write_text

__all__ = ["summarize", "table_text", "parameter_figure", "bias_figure", "write_report"]

log = logging.getLogger(__name__)

DPI = 110
MAX_BINS = 10
MAX_GROUPS = 25  # more distinct numeric values than this (Monte Carlo) are binned
_OK_COLOR, _FAIL_COLOR, _PRED_COLOR = "tab:blue", "tab:red", "black"


def _num(value) -> float:
    """A finite-or-NaN float from a table cell (None and text become NaN)."""
    if isinstance(value, bool) or value is None:
        return math.nan
    if isinstance(value, (int, float)):
        return float(value)
    return math.nan


def _is_numeric(values) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def _label(value) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, list):
        return "[" + ", ".join(_label(v) for v in value) + "]"
    return str(value)


def _groups(rows: Sequence[dict], path: str):
    """Rows grouped by the value of ``path``: (label, x, rows) in order of x.

    Numeric parameters with at most ``MAX_GROUPS`` distinct values give one group per value; more
    (Monte Carlo) give ``MAX_BINS`` equal-width bins labelled by their range. Other values (text,
    lists) give one group per distinct value, in order of first appearance, at x = 0, 1, 2...
    """
    values = [r.get(path) for r in rows]
    if not values:
        return []
    if _is_numeric(values):
        distinct = sorted(set(float(v) for v in values))
        if len(distinct) <= MAX_GROUPS:
            return [(_label(v), v, [r for r in rows if float(r[path]) == v]) for v in distinct]
        edges = np.linspace(distinct[0], distinct[-1], MAX_BINS + 1)
        idx = np.clip(np.searchsorted(edges, [float(v) for v in values], side="right") - 1,
                      0, MAX_BINS - 1)
        out = []
        for b in range(MAX_BINS):
            members = [r for r, i in zip(rows, idx, strict=True) if i == b]
            if members:
                centre = 0.5 * (edges[b] + edges[b + 1])
                out.append((f"{edges[b]:.3g}..{edges[b + 1]:.3g}", float(centre), members))
        return out
    order = list(dict.fromkeys(json.dumps(v) for v in values))
    return [(_label(json.loads(k)), float(i), [r for r in rows if json.dumps(r.get(path)) == k])
            for i, k in enumerate(order)]


def _stat(rows, column, fn):
    vals = np.array([_num(r.get(column)) for r in rows], float)
    vals = vals[np.isfinite(vals)]
    return float(fn(vals)) if vals.size else None


def summarize(rows: Sequence[dict], parameters: Sequence[dict], *, n_runs: int | None = None,
              name: str = "sweep", description: str = "") -> dict:
    """The content of ``report.json``.

    Parameters
    ----------
    rows : sequence of dict
        Result rows (``ok``, ``status``, ``error``, metric and parameter columns).
    parameters : sequence of dict
        ``{"path": ..., "label": ...}`` per swept parameter.
    n_runs : int, optional
        Runs in the sweep (default ``len(rows)``); fewer rows means an incomplete sweep.
    """
    n_ok = sum(1 for r in rows if r.get("ok"))
    statuses: dict[str, int] = {}
    for r in rows:
        statuses[r["status"]] = statuses.get(r["status"], 0) + 1
    report = {
        "name": name, "description": description,
        "runs": n_runs if n_runs is not None else len(rows), "completed_runs": len(rows),
        "ok": n_ok, "failed": len(rows) - n_ok,
        "success_rate": n_ok / len(rows) if rows else None,
        "status_counts": statuses,
        "runs_with_slip": sum(1 for r in rows if (_num(r.get("slip_events")) or 0) > 0),
        "parameters": [],
    }
    for p in parameters:
        groups = []
        for label, _x, members in _groups(rows, p["path"]):
            ok = sum(1 for r in members if r.get("ok"))
            groups.append({
                "value": label, "runs": len(members), "ok": ok, "success_rate": ok / len(members),
                "steady_lat_m_mean": _stat(members, "steady_lat_m", np.mean),
                "max_lat_m_max": _stat(members, "max_lat_m", np.max),
                "max_F_lat_ratio_max": _stat(members, "max_F_lat_ratio", np.max),
                "runs_with_slip": sum(1 for r in members if (_num(r.get("slip_events")) or 0) > 0),
            })
        report["parameters"].append({"path": p["path"], "label": p.get("label") or p["path"],
                                     "groups": groups})
    pairs = [(_num(r.get("steady_lat_m")), _num(r.get("predicted_steady_lat_m"))) for r in rows]
    pairs = [(m, q) for m, q in pairs if math.isfinite(m) and math.isfinite(q)]
    if pairs:
        dev = [abs(m - q) for m, q in pairs]
        scale = max(abs(q) for _, q in pairs)
        report["bias_prediction"] = {
            "runs": len(pairs), "max_abs_deviation_m": max(dev),
            "max_deviation_over_largest_prediction": max(dev) / scale if scale > 0 else None,
        }
    report["failures"] = [
        {"index": r["index"], "params": {p["path"]: r.get(p["path"]) for p in parameters},
         "status": r["status"], "error": r.get("error") or ""}
        for r in rows if not r.get("ok")][:100]
    return report


def _cm(value) -> str:
    v = _num(value)
    return f"{v * 100:7.2f}" if math.isfinite(v) else "      -"


def _f(value, fmt) -> str:
    v = _num(value)
    return format(v, fmt) if math.isfinite(v) else "-"


def table_text(rows: Sequence[dict], parameters: Sequence[dict], max_rows: int = 20) -> str:
    """A one-screen table: one line per run for small sweeps, else one line per parameter value."""
    if not rows:
        return "(no results)"
    lines = []
    has_pred = any(math.isfinite(_num(r.get("predicted_steady_lat_m"))) for r in rows)
    if len(rows) <= max_rows:
        names = [p.get("label") or p["path"] for p in parameters]
        width = [max(len(n), 8) for n in names]
        head = "  ".join(n.rjust(w) for n, w in zip(names, width, strict=True))
        head += "  status           steady[cm]" + (" pred[cm]" if has_pred else "")
        head += " max[cm] max|phi|[deg] F/Fmax slips"
        lines.append(head)
        for r in rows:
            cells = "  ".join(_label(r.get(p["path"]))[:w].rjust(w)
                              for p, w in zip(parameters, width, strict=True))
            line = f"{cells}  {r['status'][:16]:<16} {_cm(r.get('steady_lat_m')):>10}"
            if has_pred:
                line += f" {_cm(r.get('predicted_steady_lat_m')):>8}"
            line += (f" {_cm(r.get('max_lat_m')):>7} {_f(r.get('max_abs_phi_deg'), '13.1f'):>13}"
                     f" {_f(r.get('max_F_lat_ratio'), '6.2f'):>6}"
                     f" {_f(r.get('slip_events'), '5.0f'):>5}")
            lines.append(line)
        return "\n".join(lines)
    for p in parameters:
        lines.append(f"{p.get('label') or p['path']}:")
        lines.append(f"  {'value':>14} {'runs':>5} {'ok':>5} {'steady[cm]':>10} {'max[cm]':>8} "
                     f"{'F/Fmax':>7} {'slip runs':>9}")
        for label, _, members in _groups(rows, p["path"]):
            ok = sum(1 for r in members if r.get("ok"))
            steady = _stat(members, "steady_lat_m", np.mean)
            worst = _stat(members, "max_lat_m", np.max)
            ratio = _stat(members, "max_F_lat_ratio", np.max)
            slips = sum(1 for r in members if (_num(r.get("slip_events")) or 0) > 0)
            lines.append(f"  {label[:14]:>14} {len(members):>5} {ok:>5} {_cm(steady):>10} "
                         f"{_cm(worst):>8} {_f(ratio, '7.2f'):>7} {slips:>9}")
    return "\n".join(lines)


def _x_of(rows, path, groups):
    """x position of each row (the value, or the category index)."""
    values = [r.get(path) for r in rows]
    if _is_numeric(values):
        return np.array([float(v) for v in values])
    pos = {json.dumps(members[0].get(path)): x for _, x, members in groups}
    return np.array([pos[json.dumps(v)] for v in values])


def parameter_figure(rows: Sequence[dict], path: str, label: str | None = None,
                     only_parameter: bool = True) -> Figure:
    """Success rate, lateral tracking error and peak F_lat / friction against one parameter.

    ``only_parameter``: this is the sweep's only parameter, so the predicted offset is a function
    of it and is drawn as a line (otherwise as one mark per run).
    """
    label = label or path
    groups = _groups(rows, path)
    numeric = _is_numeric([r.get(path) for r in rows])
    fig = Figure(figsize=(7.5, 8.2))
    FigureCanvasAgg(fig)
    ax_ok, ax_err, ax_f = fig.subplots(3, 1, sharex=True)
    gx = np.array([x for _, x, _ in groups])
    rate = np.array([100.0 * sum(1 for r in m if r.get("ok")) / len(m) for _, _, m in groups])
    counts = [len(m) for _, _, m in groups]
    if numeric and len(groups) > 1:
        ax_ok.plot(gx, rate, "o-", color=_OK_COLOR)
    else:
        ax_ok.bar(gx, rate, width=0.6, color=_OK_COLOR, alpha=0.8)
    if len(groups) <= 25:
        for x, y, c in zip(gx, rate, counts, strict=True):
            ax_ok.annotate(f"n={c}", (x, y), textcoords="offset points",
                           xytext=(0, -12 if y > 15 else 8), ha="center", fontsize=7, color="0.35")
    ax_ok.set_ylim(-5, 112)
    ax_ok.set_ylabel("success rate [%]")
    ax_ok.set_title(f"{label}: {len(rows)} runs, "
                    f"{sum(1 for r in rows if r.get('ok'))} reached the goal", fontsize=11)

    x = _x_of(rows, path, groups)
    ok = np.array([bool(r.get("ok")) for r in rows])
    steady = np.array([_num(r.get("steady_lat_m")) for r in rows]) * 100
    worst = np.array([_num(r.get("max_lat_m")) for r in rows]) * 100
    pred = np.array([_num(r.get("predicted_steady_lat_m")) for r in rows]) * 100
    if np.any(np.isfinite(steady)):
        ax_err.scatter(x[ok], steady[ok], marker="o", s=26, color=_OK_COLOR,
                       label="steady offset (measured)", zorder=3)
    if np.any(np.isfinite(worst)):
        ax_err.scatter(x[ok], worst[ok], marker="^", s=30, facecolors="none",
                       edgecolors="tab:orange", label="max |lateral error|", zorder=4)
    if np.any(~ok):
        ax_err.scatter(x[~ok], worst[~ok], marker="x", s=30, color=_FAIL_COLOR,
                       label="max |lateral error|, failed run", zorder=4)
    if np.any(np.isfinite(pred)):
        order = np.argsort(x, kind="stable")
        if numeric and only_parameter:
            ax_err.plot(x[order], pred[order], "-", color=_PRED_COLOR, lw=1.2,
                        label="steady offset (predicted)", zorder=2)
        else:
            ax_err.scatter(x, pred, marker="_", s=120, color=_PRED_COLOR,
                           label="steady offset (predicted)", zorder=2)
    ax_err.axhline(0.0, color="0.6", lw=0.8)
    ax_err.set_ylabel("lateral error [cm]")
    if ax_err.get_legend_handles_labels()[0]:
        ax_err.legend(fontsize=8, loc="best")

    ratio = np.array([_num(r.get("max_F_lat_ratio")) for r in rows])
    slip = np.array([(_num(r.get("slip_events")) or 0) > 0 for r in rows])
    ax_f.scatter(x[~slip], ratio[~slip], s=22, color=_OK_COLOR, label="no slip", zorder=3)
    if np.any(slip):
        ax_f.scatter(x[slip], ratio[slip], s=30, marker="x", color=_FAIL_COLOR, label="slip",
                     zorder=4)
    ax_f.axhline(1.0, color=_FAIL_COLOR, ls="--", lw=1.0, label="friction limit")
    top = np.nanmax(ratio) if np.any(np.isfinite(ratio)) else 1.0
    ax_f.set_ylim(0.0, max(1.15, 1.1 * top))
    ax_f.set_ylabel("max |F_lat| / friction limit")
    ax_f.legend(fontsize=8, loc="upper left")
    ax_f.set_xlabel(label)
    if not numeric or (len(groups) > 0 and not _is_numeric([r.get(path) for r in rows])):
        ax_f.set_xticks(gx, [g[0] for g in groups], rotation=20, ha="right", fontsize=8)
    for ax in (ax_ok, ax_err, ax_f):
        ax.grid(alpha=0.3)
    fig.align_ylabels()
    fig.tight_layout()
    return fig


def bias_figure(rows: Sequence[dict]) -> Figure:
    """Measured steady offset against eps_eff beside the prediction, and measured vs predicted."""
    data = [(_num(r.get("eps_eff_deg")), _num(r.get("steady_lat_m")),
             _num(r.get("predicted_steady_lat_m")), bool(r.get("ok"))) for r in rows]
    data = [d for d in data if math.isfinite(d[0]) and math.isfinite(d[2])]
    eps = np.array([d[0] for d in data])
    meas = np.array([d[1] for d in data]) * 100
    pred = np.array([d[2] for d in data]) * 100
    ok = np.array([d[3] for d in data], bool)
    fig = Figure(figsize=(11, 4.6))
    FigureCanvasAgg(fig)
    ax_eps, ax_cmp = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.35, 1]})
    order = np.argsort(eps, kind="stable")
    ax_eps.plot(eps[order], pred[order], "-", color=_PRED_COLOR, lw=1.2, zorder=2,
                label="predicted (core.analysis)")
    good = ok & np.isfinite(meas)
    ax_eps.scatter(eps[good], meas[good], s=28, color=_OK_COLOR, zorder=3, label="measured")
    distinct = np.unique(np.round(eps[good], 9))
    if 1 < len(distinct) < len(eps[good]) and len(distinct) <= 30:
        for e in distinct:  # several bias combinations share one eps_eff: say how many
            same = good & (np.abs(eps - e) < 1e-6)
            count = int(np.sum(same))
            ax_eps.annotate(f"{count} run{'s' if count > 1 else ''}",
                            (e, float(np.mean(meas[same]))),
                            textcoords="offset points", xytext=(6, 6), fontsize=7, color="0.3")
    if np.any(~ok):
        ax_eps.scatter(eps[~ok], meas[~ok], s=34, marker="x", color=_FAIL_COLOR, zorder=4,
                       label="failed run")
    ax_eps.axhline(0.0, color="0.6", lw=0.8)
    ax_eps.axvline(0.0, color="0.6", lw=0.8)
    ax_eps.set_xlabel(r"effective bias $\epsilon_{eff} = \sum_k (-1)^{n-k} \epsilon_k$ [deg]")
    ax_eps.set_ylabel("steady lateral offset [cm]")
    ax_eps.set_title(f"steady offset of the last trailer ({len(data)} runs)", fontsize=11)
    ax_eps.legend(fontsize=8, loc="best")
    fin = np.isfinite(meas)
    if np.any(fin):
        lo = float(min(np.min(meas[fin]), np.min(pred)))
        hi = float(max(np.max(meas[fin]), np.max(pred)))
        pad = 0.05 * max(hi - lo, 1e-3)
        ax_cmp.plot([lo - pad, hi + pad], [lo - pad, hi + pad], "-", color="0.5", lw=1.0,
                    label="measured = predicted")
        ax_cmp.scatter(pred[fin & ok], meas[fin & ok], s=28, color=_OK_COLOR, zorder=3)
        if np.any(fin & ~ok):
            ax_cmp.scatter(pred[fin & ~ok], meas[fin & ~ok], s=34, marker="x", color=_FAIL_COLOR)
        dev = np.max(np.abs(meas[fin] - pred[fin]))
        ax_cmp.set_title(f"measured vs predicted: max deviation {dev:.2f} cm", fontsize=11)
        ax_cmp.set_aspect("equal", adjustable="datalim")
        ax_cmp.legend(fontsize=8, loc="upper left")
    ax_cmp.set_xlabel("predicted steady offset [cm]")
    ax_cmp.set_ylabel("measured steady offset [cm]")
    for ax in (ax_eps, ax_cmp):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def _slug(path: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", path).strip("_") or "parameter"


def _save(fig: Figure, path: Path) -> Path:
    return atomic_write(path, lambda partial: fig.savefig(partial, format="png", dpi=DPI))


def write_report(out_dir, rows: Sequence[dict], parameters: Sequence[dict], *,
                 n_runs: int | None = None, name: str = "sweep", description: str = "",
                 plots: bool = True, extra: dict | None = None) -> dict:
    """Write ``report.json``, ``report.html`` (the summary, the plots and the runs' table: click
    a row to see that run) and (``plots``) ``sweep_<parameter>.png`` and ``bias_offset.png``.

    Returns the report (with ``files`` listing what was written). A failing plot is logged and
    skipped; it never loses the report.
    """
    out = Path(out_dir)
    report = summarize(rows, parameters, n_runs=n_runs, name=name, description=description)
    if extra:
        report.update(extra)
    files = {"results": str(out / "results.csv"), "report": str(out / "report.json"), "plots": []}
    if plots and rows:
        for p in parameters:
            target = out / f"sweep_{_slug(p.get('label') or p['path'])}.png"
            try:
                fig = parameter_figure(rows, p["path"], p.get("label"),
                                       only_parameter=len(parameters) == 1)
                files["plots"].append(str(_save(fig, target)))
            except Exception:  # a plot must never lose the results
                log.exception("plotting %s failed", target.name)
        if any(math.isfinite(_num(r.get("predicted_steady_lat_m"))) for r in rows):
            try:
                files["plots"].append(str(_save(bias_figure(rows), out / "bias_offset.png")))
            except Exception:
                log.exception("plotting bias_offset.png failed")
    report["files"] = files
    text = json.dumps(report, indent=2, default=lambda v: None)
    atomic_write_text(out / "report.json", text)
    try:
        from pushtrain.report.html import write_table_page

        columns = list(rows[0]) if rows else []
        page = write_table_page(
            out / "report.html", f"Sweep {name}", {k: v for k, v in report.items()
                                                  if k not in ("files", "parameters")},
            columns, [[r.get(c) for c in columns] for r in rows], images=files["plots"],
            fail_column="error" if "error" in columns else None, message=description)
        files["page"] = str(page)
    except Exception:  # the page must never lose the results
        log.exception("writing report.html failed")
    return report
