"""The widest way between two places of a map, and whether the train can take it.

Widest way (:func:`widest_gap`)
    Of all ways from the start to the goal, the one whose narrowest place is widest (a
    maximin over the map's free space): the largest distance ``d*`` from the walls such that
    the distance field's nodes with at least ``d*`` join start and goal (8-connected
    components, :func:`scipy.ndimage.label`, bisected to a sixteenth of a map cell), on the
    field's own nodes (no resampling, so it agrees with any distance transform of the same
    map within one cell). Its width is ``2 d*``: wall to wall through its narrowest point, the
    widest thing that passes there. The start and the goal themselves are always open (a train
    parked in a dock only just its width is there already: the question is the way between).
Impossible here (:func:`passable`)
    The last trailer's axle midpoint carries a disc of its ``reach`` (half its width, or less
    if the rectangle is shorter) plus its clearance wherever it goes, so no way narrower than
    twice that lets it through. :func:`passable` asks it with a single labelling (cached per
    field and level), before any search; the level is lowered by half a map cell so that the
    rasterization of the map never makes a train that fits "impossible".

Lengths in metres. Node (i, j) of a :class:`~pushtrain.facility.distance_field.DistanceField`
is at ``(x0 + j h, y0 + i h)``.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np

from pushtrain.facility.distance_field import DistanceField

__all__ = ["Bottleneck", "widest_gap", "passable", "needed_half_width"]

_EIGHT = np.ones((3, 3), dtype=bool)
_LABELS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""Per distance field: {level: labels} of the levels :func:`passable` asked (a study asks many
missions on one map)."""


@dataclass(frozen=True)
class Bottleneck:
    """The narrowest place of a way: its free width [m] (wall to wall through the point) and
    where it is (x, y) [m]; ``needed`` is the width the train needs there [m]."""

    width: float
    x: float
    y: float
    needed: float

    def text(self) -> str:
        return (f"the passage at ({self.x:.2f}, {self.y:.2f}) is {self.width:.2f} m wide; "
                f"the train needs {self.needed:.2f} m")

    def to_dict(self) -> dict:
        return {"x": self.x, "y": self.y, "width": self.width, "needed": self.needed}


def needed_half_width(train, margin: float) -> float:
    """Half the width [m] of the narrowest way the last trailer of ``train`` can take with
    clearance ``margin`` [m]: the disc round its axle midpoint inside its rectangle (half its
    width, or less where the rectangle ends nearer) plus the clearance."""
    last = train.last
    reach = min(0.5 * last.width, 0.5 * last.length - abs(last.offset))
    return reach + float(margin)


def _window(field: DistanceField, x: float, y: float) -> tuple[slice, slice]:
    """The 2 x 2 nodes round (x, y) (the ones its bilinear value comes from)."""
    ny, nx = field.shape
    h = field.resolution
    j = min(max(int(math.floor((x - field.x0) / h)), 0), nx - 2)
    i = min(max(int(math.floor((y - field.y0) / h)), 0), ny - 2)
    return slice(i, i + 2), slice(j, j + 2)


def _ring(window: tuple[slice, slice], shape) -> tuple[slice, slice]:
    """``window`` grown by one node (clipped to ``shape``)."""
    (si, sj), (ny, nx) = window, shape
    return (slice(max(si.start - 1, 0), min(si.stop + 1, ny)),
            slice(max(sj.start - 1, 0), min(sj.stop + 1, nx)))


def _ends_labels(labels: np.ndarray, end: tuple[slice, slice]) -> set:
    """Labels (nonzero) of the components a forced-open end window touches."""
    ring = labels[_ring(end, labels.shape)]
    return set(np.unique(ring[ring > 0]).tolist())


def _overlap(a: tuple[slice, slice], b: tuple[slice, slice]) -> bool:
    return all(p.start < q.stop and q.start < p.stop for p, q in zip(a, b, strict=True))


def _labels(field: DistanceField, level: float, cache: bool = False) -> np.ndarray:
    from scipy import ndimage

    store = _LABELS.setdefault(field, {}) if cache else {}
    labels = store.get(level)
    if labels is None:
        labels, _ = ndimage.label(field.values >= level, structure=_EIGHT)
        if cache:
            store.clear()  # one level a field: the train's
            store[level] = labels
    return labels


def _joined(field: DistanceField, a, b, level: float, cache: bool = False) -> bool:
    if _overlap(a, b):
        return True
    labels = _labels(field, level, cache)
    return bool(_ends_labels(labels, a) & _ends_labels(labels, b))


def passable(field: DistanceField, start, goal, half_width: float) -> bool:
    """Whether a way from ``start`` to ``goal`` (x, y, ...) [m] keeps ``half_width`` [m] from
    the walls, less half a map cell (see the module docstring): False is a proof, on this map,
    that no body needing that much room gets from one to the other."""
    level = float(half_width) - 0.5 * field.resolution
    return _joined(field, _window(field, *start[:2]), _window(field, *goal[:2]), level,
                   cache=True)


def widest_gap(field: DistanceField, start, goal, half_width: float) -> Bottleneck | None:
    """The narrowest place of the widest way from ``start`` to ``goal`` (see the module
    docstring): its width ``2 d*`` and the node of it nearest to both sides it separates.
    None where no free way joins them. ``half_width`` [m] gives ``needed``."""
    from scipy import ndimage

    a, b = _window(field, *start[:2]), _window(field, *goal[:2])
    h = field.resolution
    lo, hi = 0.0, float(field.values.max())
    if not _joined(field, a, b, lo):
        return None
    if _joined(field, a, b, hi):
        lo = hi
    while hi - lo > h / 16.0:
        mid = 0.5 * (lo + hi)
        if _joined(field, a, b, mid):
            lo = mid
        else:
            hi = mid
    # the place: of the nodes that drop out between lo and hi (the way breaks there), the
    # one nearest to both pieces the way breaks into
    d = field.values
    low = _labels(field, lo)
    comp = np.isin(low, list(_ends_labels(low, a)))
    above = _labels(field, hi)
    narrow = comp & (d < hi)
    if not narrow.any():
        narrow = comp
    rows, cols = np.nonzero(narrow)
    crop = (slice(max(rows.min() - 3, 0), rows.max() + 4),
            slice(max(cols.min() - 3, 0), cols.max() + 4))
    score = np.zeros(d[crop].shape)
    for end in (a, b):
        piece = np.isin(above[crop], list(_ends_labels(above, end)))
        piece[tuple(slice(max(s.start - c.start, 0), max(s.stop - c.start, 0))
                    for s, c in zip(end, crop, strict=True))] = True
        score += (ndimage.distance_transform_edt(~piece) if piece.any()
                  else np.full(piece.shape, 1e9))
    score[~narrow[crop]] = np.inf
    i, j = np.unravel_index(int(np.argmin(score)), score.shape)
    i, j = i + crop[0].start, j + crop[1].start
    return Bottleneck(2.0 * lo, float(field.x0 + h * j), float(field.y0 + h * i),
                      2.0 * float(half_width))
