"""The distance field's bilinear lookup written out in Python, one point at a time: the
reference :meth:`pushtrain.facility.distance_field.DistanceField.at` (``pt_field_at`` in
``core/csrc/rollout.c``) is held equal to, bit for bit. SI units."""

from __future__ import annotations

import math

import numpy as np


def field_at(values: np.ndarray, x0: float, y0: float, h: float, x: float, y: float) -> float:
    """Signed distance [m] at (x, y) [m] on the grid ``values`` (ny, nx), node (i, j) at
    (x0 + j h, y0 + i h): ``-inf`` outside the nodes' rectangle or at NaN; inside, the node
    below the point (the last cell's at the far edges) and the weights a, b in [0, 1] of the
    bilinear formula."""
    ny, nx = values.shape
    u = (x - x0) / h
    v = (y - y0) / h
    if not (0.0 <= u <= nx - 1 and 0.0 <= v <= ny - 1):
        return -math.inf
    j = min(math.floor(u), nx - 2)
    i = min(math.floor(v), ny - 2)
    a = u - j
    b = v - i
    f00, f01 = float(values[i, j]), float(values[i, j + 1])
    f10, f11 = float(values[i + 1, j]), float(values[i + 1, j + 1])
    return (1.0 - b) * ((1.0 - a) * f00 + a * f01) + b * ((1.0 - a) * f10 + a * f11)
