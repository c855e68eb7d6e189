"""The planner's lookups on a grid of signed distances, in the engine's C (``core/csrc/field.c``):
the distance at points (bilinear between nodes), poses along line and arc segments, and whether
a body's outline keeps its clearance at poses.

The grid: ``values`` (ny, nx) float64, C-contiguous, node (i, j) at ``(x0 + j h, y0 + i h)``
[m]; outside the nodes' rectangle (and at NaN) the distance is ``-inf``. The Python faces of
:class:`pushtrain.facility.distance_field.DistanceField` (``at``),
:func:`pushtrain.planner.connect.sample_reference` and
:meth:`pushtrain.planner.lattice.Search.reference_clear` call these. Their readable twins, held
equal bit for bit: ``tests/reference/field_lookup.py`` and ``tests/reference/sweep.py``.
"""

from __future__ import annotations

import numpy as np

from . import native

__all__ = ["values_at", "sample_segments", "poses_clear"]

_library: list = []
"""The engine's library once loaded (any build of these files answers alike; :func:`native.load`
looks its setting up in the environment at every call, 3 us)."""


def _lib():
    if not _library:
        _library.append(native.load())
    return _library[0]


def values_at(values: np.ndarray, x0: float, y0: float, h: float, x: np.ndarray,
              y: np.ndarray) -> np.ndarray:
    """Signed distance [m] at the points (x, y) (float64 arrays of one shape, C-contiguous):
    bilinear between the nodes of ``values`` (spacing ``h`` [m], node (0, 0) at (x0, y0));
    ``-inf`` outside. An array of that shape."""
    out = np.empty(x.shape)
    ny, nx = values.shape
    _lib().pt_field_at(values.ctypes.data, ny, nx, x0, y0, h, out.size, x.ctypes.data,
                       y.ctypes.data, out.ctypes.data)
    return out


def sample_segments(pose, table: np.ndarray, spacing: float, count: int) -> np.ndarray:
    """Poses (x, y, theta) [m, m, rad] from ``pose`` along the segments of ``table`` ((m, 3)
    float64: length [m], curvature [1/m], direction +1 push / -1 pull), each in
    max(1, ceil(length / spacing)) equal steps; ``count`` is that number of steps in all (the
    caller's check of the size): (count + 1, 3), the pose first.

    Raises ValueError for a spacing that is not finite and > 0, a length that is not finite
    and >= 0, or a ``count`` that is not the table's."""
    lib = _lib()
    table = np.ascontiguousarray(table, dtype=float)
    m = table.shape[0]
    if lib.pt_sample_count(m, table.ctypes.data, float(spacing)) != count + 1:
        raise ValueError(f"sample_segments: {m} segments at spacing {spacing!r} m are not "
                         f"{count} finite steps")
    head = np.array(pose, dtype=float).reshape(3)
    out = np.empty((count + 1, 3))
    lib.pt_sample_segments(head.ctypes.data, m, table.ctypes.data, float(spacing),
                           out.ctypes.data)
    return out


def poses_clear(values: np.ndarray, x0: float, y0: float, h: float, poses: np.ndarray,
                reach: float, u: np.ndarray, v: np.ndarray, threshold: np.ndarray) -> bool:
    """Whether a body keeps its clearance at every pose of ``poses`` ((k, 3) float64,
    C-contiguous): each of its points (u, v) [m] (u along theta; float64 arrays) has a signed
    distance of at least its ``threshold`` [m]. A pose whose own distance is at least ``reach``
    [m] passes without its points; the first point that misses ends the test."""
    ny, nx = values.shape
    return bool(_lib().pt_poses_clear(
        values.ctypes.data, ny, nx, x0, y0, h, poses.shape[0], poses.ctypes.data, reach,
        u.size, u.ctypes.data, v.ctypes.data, threshold.ctypes.data))
