"""The results table as the pictures and the page read it: checks and columns (numpy only,
no matplotlib, so that the page of a run is written without it)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from pushtrain.errors import PlotError

__all__ = ["check_n", "check_data", "col", "bodies", "pose_columns", "not_finite", "finite_note",
           "drawable"]


# ---------------------------------------------------------------------------------------------
def check_n(n) -> int:
    """``n`` as an int, or :class:`PlotError` unless it is an integer >= 1."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise PlotError(f"n = {n!r}: the number of trailers must be an integer >= 1")
    return int(n)


def check_data(data, n, columns: Sequence[str]) -> int:
    """Check that ``data`` is a non-empty structured array with ``columns`` for ``n`` trailers."""
    n = check_n(n)
    names = getattr(getattr(data, "dtype", None), "names", None)
    if names is None:
        raise PlotError(
            f"data is a {type(data).__name__}: need the structured array of Result.data "
            "(one named column per recorded variable)"
        )
    missing = [c for c in columns if c not in names]
    if missing:
        raise PlotError(
            f"data lacks the column(s) {missing[:6]}{' ...' if len(missing) > 6 else ''} needed "
            f"for n = {n} trailers; it has {len(names)} columns ({', '.join(names[:6])}, ...)"
        )
    if f"x{n + 1}" in names:
        raise PlotError(
            f"n = {n} but data has a column x{n + 1}: it records more than {n} trailers"
        )
    if len(data) == 0:
        raise PlotError("data has no rows: nothing to plot")
    return n


def col(data, name: str) -> np.ndarray:
    """Column ``name`` of ``data`` as a float array."""
    return np.asarray(data[name], dtype=float)


def bodies(data, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions and headings of bodies 0..n, each of shape (rows, n+1) [m, m, rad]."""
    x = np.stack([col(data, f"x{i}") for i in range(n + 1)], axis=1)
    y = np.stack([col(data, f"y{i}") for i in range(n + 1)], axis=1)
    th = np.stack([col(data, f"theta{i}") for i in range(n + 1)], axis=1)
    return x, y, th


def pose_columns(n: int) -> list[str]:
    """The columns of time and of the poses of bodies 0..n."""
    return ["t"] + [f"{b}{i}" for b in ("x", "y", "theta") for i in range(n + 1)]


# ---------------------------------------------------------------------------------------------
# values that are not finite (a diverged or interrupted run)
# ---------------------------------------------------------------------------------------------
def not_finite(data) -> dict[str, tuple[int, float]]:
    """The float columns of ``data`` holding NaN or inf: name -> (how many rows, the first
    such row's time [s], NaN where the time itself is not finite or there is no ``t``)."""
    names = data.dtype.names or ()
    t = np.asarray(data["t"], dtype=float) if "t" in names else None
    out = {}
    for name in names:
        if data.dtype[name].kind != "f":
            continue
        bad = ~np.isfinite(np.asarray(data[name]))
        count = int(np.count_nonzero(bad))
        if count:
            first = float(t[np.argmax(bad)]) if t is not None else float("nan")
            out[name] = (count, first)
    return out


def finite_note(data, most: int = 4) -> str | None:
    """One sentence saying which columns of ``data`` hold NaN or inf (those values are not
    drawn), grouped by how many rows and from when; None if every value is finite."""
    groups: dict[tuple[int, float], list[str]] = {}
    for name, key in not_finite(data).items():
        groups.setdefault(key, []).append(name)
    if not groups:
        return None
    rows = len(data)
    parts = []
    for (count, first), names in list(groups.items())[:most]:
        shown = ", ".join(names[:6]) + (f" and {len(names) - 6} more" if len(names) > 6 else "")
        since = f" from t = {first:.2f} s" if math.isfinite(first) else ""
        parts.append(f"{shown} ({count} of {rows} rows{since})")
    more = len(groups) - most
    return ("not finite (NaN or inf), not drawn: " + "; ".join(parts)
            + (f"; and {more} more group{'s' if more > 1 else ''} of columns" if more > 0 else ""))


def drawable(data, columns: Sequence[str] = ()) -> np.ndarray:
    """``data`` ready to draw: inf as NaN (a line breaks there instead of running off the
    axes), without the rows whose time, or any of ``columns``, is not finite (a pose with a
    NaN cannot be drawn). ``data`` itself if nothing changes."""
    names = data.dtype.names or ()
    floats = [n for n in names if data.dtype[n].kind == "f"]
    keep = np.ones(len(data), dtype=bool)
    for name in ["t", *columns]:
        if name in names and data.dtype[name].kind == "f":
            keep &= np.isfinite(np.asarray(data[name]))
    infinite = [n for n in floats if np.isinf(np.asarray(data[n])).any()]
    if keep.all() and not infinite:
        return data
    out = data[keep]  # a copy
    for name in infinite:
        column = out[name]
        column[np.isinf(column)] = np.nan
    return out
