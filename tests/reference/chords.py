"""The passage widths written out in Python, one chord at a time: the reference
:func:`pushtrain.planner.passage.chords` (and so ``width_across``, ``shortest_chord(s)``) is held
equal to (``tests/planner/test_passage.py``). SI units, radians."""

from __future__ import annotations

import math

import numpy as np


def chord(field, x: float, y: float, heading: float, reach: float) -> float:
    """Free width [m] through (x, y) [m] across ``heading`` [rad]: along the normal
    (-sin, cos), samples every half cell from ``-reach`` to ``reach`` [m]; from the sample
    nearest the point, walk outward one sample at a time, each way, while the field is > 0
    (off the map counts as a wall); where it is not, the wall lies between the last free
    sample and that one, at the field's linear zero crossing; a way that stays free ends at
    its last sample. 0 where the point's own sample is not free."""
    h = 0.5 * field.resolution
    t = np.arange(-reach, reach + h, h)  # the sample offsets along the normal [m]
    values = field.at(x - t * math.sin(heading), y + t * math.cos(heading))
    d = [float(v) if math.isfinite(v) else -1.0 for v in values]
    middle = min(range(len(t)), key=lambda k: abs(t[k]))
    if d[middle] <= 0.0:
        return 0.0
    ends = []
    for step in (1, -1):
        k = middle
        while 0 <= k + step < len(t) and d[k + step] > 0.0:
            k += step
        if 0 <= k + step < len(t):  # wall at k + step: interpolate where d crosses zero
            a, b = d[k], d[k + step]
            ends.append(t[k] + (t[k + step] - t[k]) * a / (a - b))
        else:
            ends.append(t[k])
    return ends[0] - ends[1]


def shortest_chord(field, x: float, y: float, reach: float, directions: int = 36) -> float:
    """The smallest :func:`chord` [m] through (x, y) over ``directions`` headings evenly
    spaced over [0, pi)."""
    return min(chord(field, x, y, k * (math.pi / directions), reach) for k in range(directions))
