"""The results table as the pictures and the page read it: checks and columns (numpy only,
no matplotlib, so that the page of a run is written without it)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pushtrain.errors import PlotError

__all__ = ["check_n", "check_data", "col", "bodies", "pose_columns"]


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
