"""``report.html``: one self-contained page of a run (or of a failed plan) to open in a browser.

The page shows the map (walls, keep-out band, planned path, reference, traces) with the train
drawn at its real size at the time a slider picks (play/pause, 0.25x-8x), zoom and pan on the
map, the time series with a cursor that follows the slider (a click on a plot moves the train to
that time) and the summary as a table. For a failed plan it shows the search tree, the best
partial plan, the failure points and the bottleneck instead of a run.

Why a small canvas renderer of our own (``web/report.js``) rather than a plotting library:
the page must hold a run in at most 5 MB with no network; Plotly's offline bundle alone is
about 3.5 MB, and drawing a few rectangles and polylines per frame needs nothing it offers.
The renderer is about 500 lines of plain JavaScript with no dependencies.

The map is embedded as a PNG picture of the free space drawn with Pillow from the map's data
(:mod:`~pushtrain.report.map_picture`: polygons and occupancy grids look as in ``map.png``),
with its extent in metres; everything else is vector data. Nothing here imports matplotlib.
The time series are decimated for the view to at most ``max_rows`` rows spread evenly over
the results, first and last included (:func:`~pushtrain.report.geometry.frame_indices`, as the
GIF's frames; each drawn pose is a row of ``results.npz`` exactly); ``results.npz`` itself is
never decimated.
"""

from __future__ import annotations

import base64
import json
import math
import re
from collections.abc import Sequence
from importlib import resources
from pathlib import Path

import numpy as np

from pushtrain.files import atomic_write_text
from pushtrain.report.data import check_n, finite_note
from pushtrain.report.geometry import DEFAULT_FOOTPRINTS, frame_indices
from pushtrain.report.map_picture import map_picture

__all__ = ["HTML_FILE", "MAX_ROWS", "run_payload", "failure_payload", "write_html",
           "plot_report", "plot_failure_report", "write_table_page"]

HTML_FILE = "report.html"
MAX_ROWS = 4000
"""Most rows of the results the page carries (the view's decimation)."""
MAX_VALUES = 500_000
"""Most numbers the page carries over time (rows x columns): a long train gets fewer rows
(50 trailers: about 1,900), so that its page stays within a few MB and is written in tenths
of a second."""
MAP_PIXELS = 2400
"""Longest side of the map's picture [px] (cells of real maps stay visible up to 1/20 m)."""
MAX_OUTLINE_POINTS = 60_000
"""Most points of the keep-out band drawn (a band of more points is left out, and said so)."""


class _Finite(list):
    """A list already free of non-finite floats (from :func:`_rounded`): :func:`_finite`
    passes it as it is instead of walking its thousands of values again."""


def _rounded(a, digits: int = 4) -> list:
    """``a`` as a JSON-ready list, rounded, with non-finite values as None."""
    a = np.round(np.asarray(a, dtype=float), digits)
    finite = np.isfinite(a)
    if finite.all():
        return _Finite(a.tolist())
    return _Finite(v if ok else None for v, ok in zip(a.tolist(), finite.tolist(), strict=True))


def _keep_out(world, margin: float | None) -> dict | None:
    """The free space shrunk by ``margin`` [m] as rings of points, or None."""
    if world is None or not margin or margin <= 0.0:
        return None
    band = world.eroded(margin).simplify(0.01)
    rings = []
    for poly in getattr(band, "geoms", [band]):
        if poly.is_empty or not hasattr(poly, "exterior"):
            continue
        for ring in [poly.exterior, *poly.interiors]:
            rings.append(np.asarray(ring.coords))
    total = sum(len(r) for r in rings)
    if total > MAX_OUTLINE_POINTS:
        return {"margin": margin, "rings": [], "omitted": total}
    return {"margin": margin, "rings": [[_rounded(r[:, 0], 3), _rounded(r[:, 1], 3)]
                                        for r in rings]}


def _base(n: int, world, footprints, keep_out, title: str) -> dict:
    fp = dict(DEFAULT_FOOTPRINTS)
    fp.update(footprints or {})
    return {"format": "pushtrain-report", "version": 1, "title": title, "n": n,
            "footprints": {k: [float(v[0]), float(v[1])] for k, v in fp.items()},
            "map": None if world is None else map_picture(world, MAP_PIXELS),
            "keep_out": _keep_out(world, keep_out)}


def run_payload(data, n: int, *, world=None, path_xy=None, footprints=None, status=None,
                summary: dict | None = None, phi_max_deg: float | None = None,
                keep_out: float | None = None, max_rows: int = MAX_ROWS,
                title: str | None = None, max_values: int = MAX_VALUES) -> dict:
    """What the page of a co-simulation run shows, as plain data.

    ``data`` is ``Result.data`` (columns as in ``master._columns(n)``); ``world`` the map or
    None; ``path_xy`` (N, 2) the planned path of the last trailer [m]; ``footprints`` as in
    :func:`~pushtrain.report.mapview.plot_map`; ``phi_max_deg`` the joint limit drawn on the
    joint plot; ``keep_out`` the clearance [m] whose band is drawn.

    At most ``max_rows`` rows, and at most ``max_values`` numbers over time in all, spread
    evenly over the rows whose time is finite. Values that are not finite (a diverged run) are
    left out of the drawing (JSON null) and ``notes`` says which.
    """
    n = check_n(n)
    names = set(data.dtype.names)
    per_row = 5 * n + 12  # poses, reference, speeds, joints, errors, forces
    timed = np.flatnonzero(np.isfinite(np.asarray(data["t"], dtype=float)))
    rows = timed[frame_indices(len(timed), min(max_rows, max(2, max_values // per_row)))]
    notes = [note for note in (finite_note(data),) if note]
    if len(rows) == 0:
        notes.append("the results have no row with a finite time: nothing to show over time")

    def col(name):
        return _rounded(np.asarray(data[name], dtype=float)[rows])

    t = col("t")
    bodies = [{"x": col(f"x{i}"), "y": col(f"y{i}"), "theta": col(f"theta{i}")}
              for i in range(n + 1)]
    series = []

    def panel(key, title, unit, lines, limits=()):
        series.append({"key": key, "title": title, "unit": unit, "lines": lines,
                       "limits": list(limits)})

    def line(name, values, style="solid", color=None):
        return {"name": name, "y": values, "style": style, "color": color}

    deg = 180.0 / math.pi

    if {"v0", "v_cmd"} <= names:
        panel("speed", "Robot speed", "m/s",
              [line("v robot", col("v0"), color="#d62728"),
               line("v commanded", col("v_cmd"), "dashed", "#111111")])
    if {"w0", "w_cmd"} <= names:  # deg/s, as in inputs_joints.png
        panel("yaw_rate", "Robot yaw rate", "deg/s",
              [line("w robot", _rounded(np.asarray(data["w0"], float)[rows] * deg, 3),
                    color="#d62728"),
               line("w commanded", _rounded(np.asarray(data["w_cmd"], float)[rows] * deg, 3),
                    "dashed", "#111111")])
    phis = [line(f"phi{i}", _rounded(np.asarray(data[f"phi{i}"], float)[rows] * deg, 3))
            for i in range(1, n + 1) if f"phi{i}" in names]
    if phis:
        limits = []
        if phi_max_deg:
            limits = [{"name": f"joint limit ±{phi_max_deg:g} deg", "y": float(phi_max_deg)},
                      {"name": None, "y": -float(phi_max_deg)}]
        panel("joints", "Joint angles", "deg", phis, limits)
    if "e_lat" in names:
        panel("lateral", "Lateral tracking error (last trailer)", "cm",
              [line("lateral error", _rounded(np.asarray(data["e_lat"], float)[rows] * 100, 3))])
    if "e_theta" in names:
        panel("heading", "Heading tracking error (last trailer)", "deg",
              [line("heading error",
                    _rounded(np.asarray(data["e_theta"], float)[rows] * deg, 3))])
    ratios = []
    for i in range(1, n + 1):
        if {f"F_lat{i}", f"F_lat_max{i}"} <= names:
            f = np.abs(np.asarray(data[f"F_lat{i}"], float)[rows])
            fmax = np.asarray(data[f"F_lat_max{i}"], float)[rows]
            with np.errstate(divide="ignore", invalid="ignore"):
                ratios.append(line(f"trailer {i}", _rounded(np.where(fmax > 0, f / fmax,
                                                                     np.nan), 4)))
    if ratios:
        panel("force", "Lateral wheel force / friction limit", "-", ratios,
              [{"name": "friction limit (slip above)", "y": 1.0}])
    out = _base(n, world, footprints, keep_out,
                title or f"Robot with {n} trailer{'s' if n > 1 else ''}"
                + (f": {status.replace('_', ' ')}" if status else ""))
    out.update({
        "kind": "run", "status": status, "rows": rows.tolist(), "t": t, "bodies": bodies,
        "reference": ({"x": col("x_d"), "y": col("y_d")} if {"x_d", "y_d"} <= names
                      else None),
        "path": None if path_xy is None else [_rounded(np.asarray(path_xy)[:, 0]),
                                              _rounded(np.asarray(path_xy)[:, 1])],
        "series": series if len(rows) else [], "summary": summary or {}, "notes": notes,
    })
    return out


def failure_payload(n: int, details: dict, *, world=None, footprints=None, start=None,
                    goal=None, message: str = "", reason: str | None = None,
                    keep_out: float | None = None) -> dict:
    """What the page of a failed plan shows: ``details`` is a PlanningError's ``details``
    (``tree``, ``closest``, ``failure_points``, ``bottleneck``, ``route``); ``start`` and
    ``goal`` are the last trailer's poses (x, y, theta); ``message`` and ``reason`` the
    error's."""
    n = check_n(n)
    details = details or {}
    tree = []
    for trace in details.get("tree") or []:
        xy = np.asarray(trace, dtype=float)
        if xy.ndim == 2 and xy.shape[0] > 1:
            tree.append([_rounded(xy[:, 0], 3), _rounded(xy[:, 1], 3)])
    partial = None
    closest = details.get("closest") or {}
    if closest.get("segments") and start is not None:
        from pushtrain.core.reference import path_points
        from pushtrain.core.segment import Segment

        x, y = path_points(start, [Segment.from_dict(g) for g in closest["segments"]])
        partial = [_rounded(x), _rounded(y)]
    train = None
    if closest.get("x") is not None:
        train = {"x": _rounded(closest["x"]), "y": _rounded(closest["y"]),
                 "theta": _rounded(closest["headings"])}
    route = details.get("route") or {}
    bottleneck = details.get("bottleneck")
    if bottleneck:  # the widest way's narrowest place, or the place the train cannot turn
        bottleneck = {"what": "bottleneck", **bottleneck}
    out = _base(n, world, footprints, keep_out, f"Planning failed with {n} trailer"
                f"{'s' if n > 1 else ''}")
    out.update({
        "kind": "failure", "status": "planning_failed", "message": message,
        "tree": tree, "partial": partial, "train": train,
        "route": ([_rounded(np.asarray(route["points"])[:, 0]),
                   _rounded(np.asarray(route["points"])[:, 1])]
                  if route.get("points") else None),
        "bottleneck": bottleneck,
        "failure_points": [{"x": p["x"], "y": p["y"], "kind": p.get("kind", "collision"),
                            "body": p.get("body")}
                           for p in (details.get("failure_points") or [])],
        "start": None if start is None else [float(v) for v in start[:3]],
        "goal": None if goal is None else [float(v) for v in goal[:3]],
        "summary": {"status": "planning_failed", "reason": reason or details.get("reason"),
                    "impossible here": bool(details.get("impossible")),
                    "message": message},
    })
    return out


def _asset(name: str) -> str:
    return resources.files("pushtrain.report").joinpath("web", name).read_text("utf-8")


def write_table_page(path, title: str, summary: dict, columns: Sequence[str],
                     rows: Sequence[Sequence], *, images: Sequence[Path] = (),
                     fail_column: str | None = None, message: str = "") -> Path:
    """A page of many runs (a sweep, an atlas): ``summary`` as a table, the PNG ``images``
    inlined, and the runs as a table of ``columns`` x ``rows`` that sorts by a column and shows
    one run when its row is clicked (cells of ``fail_column`` that are not empty in red).
    Written atomically, self-contained like :func:`write_html`."""
    payload = {"title": title, "message": message, "summary": summary,
               "columns": list(columns), "rows": [list(r) for r in rows],
               "fail_column": fail_column,
               "images": [{"name": Path(p).name,
                           "png": base64.b64encode(Path(p).read_bytes()).decode("ascii")}
                          for p in images if Path(p).is_file()]}
    return _page(path, payload, "table.html", "table.js", "table.css")


def write_html(path, payload: dict) -> Path:
    """Write the page of ``payload`` to ``path`` atomically: one file, scripts, styles and
    data inlined (no network)."""
    return _page(path, payload, "run.html", "report.js")


def _finite(obj):
    """``obj`` with every non-finite float (NaN, inf) as None: JSON has no such numbers."""
    if isinstance(obj, _Finite):
        return obj
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {str(k): _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if isinstance(obj, np.generic):
        return _finite(obj.item())
    return obj


def _page(path, payload: dict, body: str, script: str, css: str | None = None) -> Path:
    """Write the page: ``web/page.html`` around the ``body`` part, with the shared styles
    (``report.css``), the part's own (``css``), its ``script`` and the ``payload``."""
    data = json.dumps(_finite(payload), separators=(",", ":"), allow_nan=False, default=str)
    data = data.replace("</", "<\\/")  # the JSON cannot end its <script> element
    title = payload.get("title", "pushtrain").replace("&", "&amp;").replace("<", "&lt;")
    styles = _asset("report.css") + (_asset(css) if css else "")
    parts = {"BODY": _asset(body), "TITLE": title, "CSS": styles, "JS": _asset(script),
             "DATA": data}
    # one pass over the template: a marker inside a part (a title, the data) stays as it is
    page = re.sub(r"\{\{(BODY|TITLE|CSS|JS|DATA)\}\}", lambda m: parts[m.group(1)],
                  _asset("page.html"))
    return atomic_write_text(Path(path), page)


def plot_report(data, n: int, out_path, **kwargs) -> Path:
    """:func:`run_payload` of ``data`` written to ``out_path`` (see :func:`write_html`)."""
    return write_html(out_path, run_payload(data, n, **kwargs))


def plot_failure_report(n: int, details: dict, out_path, **kwargs) -> Path:
    """:func:`failure_payload` written to ``out_path``."""
    return write_html(out_path, failure_payload(n, details, **kwargs))
