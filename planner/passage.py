"""The widest way between two places of a map, and whether the train can take it.

Widest way (:func:`widest_gap`)
    Of all ways from the start to the goal, the one whose narrowest place is widest (a
    maximin over the map's free space): the largest distance ``d*`` from the walls such that
    the distance field's nodes with at least ``d*`` join start and goal (8-connected
    components, :func:`scipy.ndimage.label`, bisected to a sixteenth of a map cell), on the
    field's own nodes (no resampling, so it agrees with any distance transform of the same
    map within one cell). Its width is ``2 d*`` plus what the nodes miss of the passage's
    middle (at most one cell: the shortest chord through its narrowest node, wall to wall, is
    never below ``2 d*`` and exact across straight walls), so a message does not name a
    passage narrower than the map's. The start and the goal themselves are always open (a
    train parked in a dock only just its width is there already: the question is the way
    between).
Impossible here (:func:`passable`)
    The last trailer's axle midpoint carries a disc of its ``reach`` (half its width, or less
    if the rectangle is shorter) plus its clearance wherever it goes, so no way narrower than
    twice that lets it through. :func:`passable` asks it with a single labelling (cached per
    field and level), before any search; the level is lowered by half a cell diagonal (a way
    between the nodes is at most that much wider than the nodes beside it: the field is
    1-Lipschitz), so that the sampling of the map never makes a train that fits
    "impossible".

Turning (:func:`swept_band`, :func:`corner_need`, :func:`tight_corners`)
    On a steady arc whose last trailer's axle midpoint runs on a circle of radius ``rho``,
    body i's midpoint runs on ``rho_i`` (``rho_{i-1}² = rho_i² - R_{i-1}² + F_i²``, the chain's
    steady off-tracking; all equal when F = R) with its rectangle tangent there, so the train
    sweeps the ring between ``r_in = min_i (rho_i - w_i/2) - m_i`` (the inner side at the
    axle) and ``r_out = max_i sqrt((rho_i + w_i/2)² + e_i²) + m_i`` (the outer corner farthest
    along, ``e_i = |offset_i| + l_i/2``), margins ``m_i`` included. Turning by ``turn`` round
    the inside corner of two corridors of width ``W``, the ring's centre can sit behind that
    corner at most ``r_in`` from it, which gives back ``r_in cos(turn/2)`` of corridor: the
    corner needs ``W >= r_out - r_in cos(turn / 2)`` (a straight corridor the ring's width,
    a right-angle corner more). Links enter through ``rho_i``; the number of trailers
    through the bodies on the ring (and, not counted here, the transients entering an arc, in
    which followers cut inside by 0.1-0.2 m: the bound is what a steady turn needs at least).
    :func:`tight_corners` finds the corners of a route (turns of more than 30 deg within
    2 m) and measures the corridors' widths across each leg on the distance field (the
    shortest chord through the route within 1.5 m of the corner: a door in a thin wall
    counts; never less than the widest way's through the corner, as a chord cutting a
    ragged jamb's corner can be).

Lining up with a door (:func:`door_need`)
    A leg that narrows for at most 0.5 m within 1.5 m of the corner and opens wider beyond
    is a door of width ``D`` in a wall ``t`` thick (the narrow stretch's length) off a
    corridor of width ``W`` (the other leg's). Turning into it by about a right angle, the
    ring's centre ``(cx, cy)`` (door wall's face ``y = 0``, door ``0 <= x <= D``, corridor
    ``0 <= y <= W``, the wall ``-t <= y <= 0`` either side of the door) must keep the quarter
    ring (the turn from along the corridor to down through the door) off both pieces of wall
    (along every ray from the centre, the part of the ring within the wall's band lies
    between the jambs), the straight train along the corridor before it above the wall
    (``cy + radius >= a``, ``a`` the widest body's half width with its clearance) and the
    straight train leaving it, on ``x = cx + radius``, in the door (``a <= cx + radius <=
    D - a``); the corridor then needs ``W >= cy + r_out`` (the ring's top, where the train
    runs along it), least over those centres. A door need not be narrower than the
    corridor: a 0.9 m door off a 0.8 m corridor is the corridor's problem, not the door's.

Lengths in metres, angles in radians. Node (i, j) of a
:class:`~pushtrain.facility.distance_field.DistanceField` is at ``(x0 + j h, y0 + i h)``.
"""

from __future__ import annotations

import functools
import math
import weakref
from dataclasses import dataclass

import numpy as np
from scipy import ndimage  # at import (0.1-0.3 s once), not in the first search

from pushtrain.facility.distance_field import DistanceField

__all__ = ["Bottleneck", "widest_gap", "passable", "needed_half_width", "SweptBand",
           "swept_band", "corner_need", "door_need", "Door", "Corner", "tight_corners",
           "width_across", "shortest_chord", "shortest_chords", "chords", "CHORD_DIRECTIONS"]

_EIGHT = np.ones((3, 3), dtype=bool)
_LABELS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""Per distance field: {level: labels} of the levels :func:`passable` asked (a study asks many
missions on one map)."""
_CACHE_NODES = 4_000_000
"""Largest field whose labels are kept (16 MB of int32); a larger one is labelled again."""


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
    cache = cache and field.values.size <= _CACHE_NODES
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
    the walls, less half a cell diagonal (see the module docstring): False is a proof, on this map,
    that no body needing that much room gets from one to the other."""
    level = float(half_width) - math.sqrt(0.5) * field.resolution
    return _joined(field, _window(field, *start[:2]), _window(field, *goal[:2]), level,
                   cache=True)


def widest_gap(field: DistanceField, start, goal, half_width: float) -> Bottleneck | None:
    """The narrowest place of the widest way from ``start`` to ``goal`` (see the module
    docstring): the node of it nearest to both sides it separates, and its width (``2 d*``
    to ``2 d* + h``: the shortest chord through that node, wall to wall, within that).
    None where no free way joins them. ``half_width`` [m] gives ``needed``."""
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
    # of equally good nodes (a slit, a corridor of even width), the one amid them
    ti, tj = np.nonzero(score <= score.min() + 1e-9)
    k = int(np.argmin((ti - ti.mean()) ** 2 + (tj - tj.mean()) ** 2))
    i, j = ti[k] + crop[0].start, tj[k] + crop[1].start
    x, y = float(field.x0 + h * j), float(field.y0 + h * i)
    # its width wall to wall: the nodes' 2 d* misses up to a cell where the passage's middle
    # falls between nodes; the shortest chord through the node (never below 2 d*: each half
    # reaches at least d*) says how much, exactly where the walls run straight across
    chord = shortest_chord(field, x, y)
    return Bottleneck(min(max(2.0 * lo, chord), 2.0 * lo + h), x, y, 2.0 * float(half_width))


# --------------------------------------------------------------------------- turning
@dataclass(frozen=True)
class SweptBand:
    """The ring a train sweeps on a steady arc (see the module docstring): the last trailer's
    ``radius`` [m], the ring's inner and outer radii ``r_in``, ``r_out`` [m] (margins
    included)."""

    radius: float
    r_in: float
    r_out: float
    half_straight: float = 0.0
    """Half the width [m] of the straight train's band: its widest body's, clearance
    included."""

    @property
    def width(self) -> float:
        """Width [m] of the ring: what a steady turn needs in a gently bending corridor."""
        return self.r_out - self.r_in


def swept_band(train, radius: float, margins) -> SweptBand:
    """The :class:`SweptBand` of ``train`` whose last trailer turns on ``radius`` [m], each
    body keeping ``margins[i]`` [m] (robot first)."""
    front, rear = train.geometry.front, train.geometry.rear
    n = train.n
    rho = np.empty(n + 1)
    rho[n] = float(radius)
    for i in range(n, 0, -1):  # rho_{i-1}² = rho_i² - R_{i-1}² + F_i²
        rho[i - 1] = math.sqrt(max(rho[i] ** 2 - rear[i - 1] ** 2 + front[i - 1] ** 2, 0.0))
    r_in, r_out, half = math.inf, 0.0, 0.0
    for i, body in enumerate(train.bodies):
        m = float(margins[i])
        along = abs(body.offset) + 0.5 * body.length
        r_out = max(r_out, math.hypot(rho[i] + 0.5 * body.width, along) + m)
        r_in = min(r_in, rho[i] - 0.5 * body.width - m)
        half = max(half, 0.5 * body.width + m)
    return SweptBand(float(radius), max(r_in, 0.0), r_out, half)


def corner_need(band: SweptBand, turn: float) -> float:
    """Width [m] of corridor a steady turn by ``turn`` [rad] (0 to pi) round an inside corner
    needs: ``r_out - r_in cos(turn / 2)`` (module docstring)."""
    turn = min(abs(float(turn)), math.pi)
    return band.r_out - band.r_in * math.cos(0.5 * turn)


def chords(field: DistanceField, x, y, headings, reach: float = 5.0) -> np.ndarray:
    """Free widths [m] wall to wall through the points (x, y) [m] (P,) across each direction
    ``headings`` [rad] (A,) or (P, A) (each point's own): (P, A), along the normal of each
    heading, the field's zero crossings interpolated (half-cell samples); 0 where the point
    is in a wall, ``2 reach`` at most. One call to the field for every point and direction."""
    h = 0.5 * field.resolution
    t = np.arange(-reach, reach + h, h)
    k0 = int(np.argmin(np.abs(t)))
    x = np.atleast_1d(np.asarray(x, dtype=float))[:, None, None]
    y = np.atleast_1d(np.asarray(y, dtype=float))[:, None, None]
    headings = np.asarray(headings, dtype=float)
    headings = headings[:, :, None] if headings.ndim == 2 else np.atleast_1d(headings)[None, :,
                                                                                      None]
    d = field.at(x - t * np.sin(headings), y + t * np.cos(headings))  # (P, A, T)
    d[~np.isfinite(d)] = -1.0
    ends = []
    for side, t_side, sign in ((d[..., k0:], t[k0:], 1.0), (d[..., k0::-1], t[k0::-1], -1.0)):
        # from the point outwards, one way: the last free sample, then the wall interpolated
        wall = side[..., 1:] <= 0.0
        hit = wall.any(axis=-1)
        k = np.where(hit, np.argmax(wall, axis=-1), side.shape[-1] - 1)
        a = np.take_along_axis(side, k[..., None], axis=-1)[..., 0]
        b = np.take_along_axis(side, np.minimum(k + 1, side.shape[-1] - 1)[..., None],
                               axis=-1)[..., 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            ends.append(t_side[k] + np.where(hit, sign * h * a / (a - b), 0.0))
    return np.where(d[..., k0] > 0.0, ends[0] - ends[1], 0.0)


def door_need(band: SweptBand, door: float, wall: float = 0.0, step: float = 0.001) -> float:
    """Width [m] of corridor in front of a door ``door`` [m] wide in a wall ``wall`` [m]
    thick that a steady right-angle turn into it on ``band`` needs (module docstring): the
    lowest ring centre, scanned every ``step`` [m], for which some sideways place keeps the
    quarter ring and the straight train before and after it off both pieces of wall; inf if
    none does (the door is narrower than the straight train)."""
    r, big, rho, a = band.r_in, band.r_out, band.radius, band.half_straight
    t = max(float(wall), 0.0)
    theta = np.linspace(0.0, 0.5 * math.pi, 721)
    sin, cos = np.sin(theta), np.cos(theta)
    edge = sin < 1e-12
    for cy in np.arange(a - rho, big, step):  # a straight train along the corridor: cy >= a - rho
        # the quarter ring's points in the wall's band -t <= y <= 0, along each ray from the
        # centre: s from s0 to s1 (x = cx + s cos(theta))
        with np.errstate(divide="ignore", invalid="ignore"):
            s0 = np.where(edge, r, np.maximum(r, (-t - cy) / sin))
            s1 = np.where(edge, big, np.minimum(big, -cy / sin))
        hit = s0 <= s1
        hit &= ~edge | ((-t <= cy) & (cy <= 0.0))
        lo_x, hi_x = -math.inf, math.inf  # the centre's x keeping off the near / far wall
        if hit.any():
            lo_x = -float(np.min(s0[hit] * cos[hit]))
            hi_x = door - float(np.max(s1[hit] * cos[hit]))
        if cy > -t:  # the straight train leaving the arc crosses the wall: in the door
            lo_x, hi_x = max(lo_x, a - rho), min(hi_x, door - a - rho)
        if lo_x <= hi_x:
            return float(cy + big)
    return math.inf


@dataclass(frozen=True)
class Door:
    """A door a route turns through: where (x, y) [m] (the narrow stretch's middle), its
    ``width`` [m], its ``wall`` [m] (the narrow stretch's length along the route) and the
    width [m] of the ``corridor`` in front of it."""

    x: float
    y: float
    width: float
    wall: float
    corridor: float


def _door(route, field: DistanceField, sc: float, offsets, widths) -> Door | None:
    """The door of the corner at ``sc`` [m] along ``route`` (module docstring), or None.
    ``widths`` [m] are the shortest chords at ``offsets`` [m] from the corner: a door is a
    dip in one leg, at most 0.5 m long, with wider samples (by 0.15 m) on both sides of it
    (toward the corner the corridor's mouth, beyond it a room); the other leg is the
    corridor. Its width is the widest way's through it (:func:`widest_gap` on the field
    within 1.2 m of it, between the route 0.3 m either side): a chord through a route point
    off the door's middle, or cutting a ragged jamb, can be narrower than the door."""
    offsets, widths = np.asarray(offsets), np.asarray(widths, dtype=float)
    best = None
    for side in (1.0, -1.0):
        leg = side * offsets > 0.0
        order = np.argsort(np.abs(offsets[leg]))
        w, o = widths[leg][order], np.abs(offsets[leg])[order]
        for k in np.argsort(w, kind="stable"):
            first, last = k, k  # the narrow stretch round sample k
            while first > 0 and w[first - 1] <= w[k] + 0.05:
                first -= 1
            while last + 1 < w.size and w[last + 1] <= w[k] + 0.05:
                last += 1
            depth = o[last] - o[first] + 0.05
            if (first == 0 or last + 1 == w.size or depth > 0.5
                    or w[:first].max() < w[k] + 0.15 or w[last + 1:].max() < w[k] + 0.15):
                continue
            other = widths[~leg][np.abs(offsets[~leg]) >= 0.5]
            if other.size and (best is None or w[k] < best[0]):
                best = (float(w[k]), side, o[first], o[last], float(depth),
                        float(np.median(other)))
            break
    if best is None:
        return None
    _, side, near, far, depth, corridor = best
    x, y, _ = route.pose_at(sc + side * 0.5 * (near + far))
    ends = [route.pose_at(sc + side * o) for o in (max(near - 0.3, 0.0), far + 0.3)]
    gap = widest_gap(_crop(field, x, y, 1.2), ends[0], ends[1], 0.0)
    width = w_min = best[0]
    if gap is not None:
        width = max(gap.width, w_min)
    return Door(float(x), float(y), float(width), depth, corridor)


def _door_need_at_least(band: SweptBand, lower: float) -> float:
    """A lower bound [m] of the corridor a door found where every chord is at least ``lower``
    [m] wide may need: :func:`door_need` of a door ``lower`` wide (rounded down to 1 cm; a
    door is at least its narrowest chord wide, and a wider door needs less) in a 0.5 m wall
    (the thickest :func:`_door` takes; a thicker wall needs more)."""
    return _door_need_cached(band, math.floor(100.0 * lower) / 100.0)


@functools.lru_cache(maxsize=256)
def _door_need_cached(band: SweptBand, door: float) -> float:
    return door_need(band, door, 0.5)


def _crop(field: DistanceField, x: float, y: float, half: float) -> DistanceField:
    """The nodes of ``field`` within ``half`` [m] of (x, y) (a square), as a field."""
    h = field.resolution
    ny, nx = field.shape
    j0 = max(int(math.floor((x - half - field.x0) / h)), 0)
    i0 = max(int(math.floor((y - half - field.y0) / h)), 0)
    j1 = min(int(math.ceil((x + half - field.x0) / h)) + 1, nx)
    i1 = min(int(math.ceil((y + half - field.y0) / h)) + 1, ny)
    return DistanceField(field.values[i0:i1, j0:j1], field.x0 + j0 * h, field.y0 + i0 * h, h)


def width_across(field: DistanceField, x: float, y: float, heading: float,
                 reach: float = 5.0) -> float:
    """Free width [m] of the corridor through (x, y) across the direction ``heading`` [rad]:
    wall to wall along the normal (the field's zero crossings, interpolated); 0 in a wall."""
    return float(chords(field, [x], [y], [heading], reach)[0, 0])


CHORD_DIRECTIONS = np.linspace(0.0, math.pi, 36, endpoint=False)
"""The directions [rad] :func:`shortest_chord` tries (a chord 2.5 deg off is 0.1 % long)."""


def shortest_chords(field: DistanceField, x, y, reach: float = 2.5) -> np.ndarray:
    """The shortest chord [m] through each point (x, y) (P,), wall to wall, over
    :data:`CHORD_DIRECTIONS`: a corridor's or a door's width wherever in it the point is (at
    least twice the point's distance from the walls); chords longer than ``2 reach`` count as
    ``2 reach``. Points are measured a few at a time, so that the samples of one call to the
    field stay under about :data:`CHORD_SAMPLES` (memory: a 2 cm map's chords have 500 samples
    each)."""
    x = np.atleast_1d(np.asarray(x, dtype=float))
    y = np.atleast_1d(np.asarray(y, dtype=float))
    per_point = CHORD_DIRECTIONS.size * (2.0 * reach / (0.5 * field.resolution) + 2.0)
    step = max(1, int(CHORD_SAMPLES // per_point))
    return np.concatenate([chords(field, x[k:k + step], y[k:k + step], CHORD_DIRECTIONS,
                                  reach).min(axis=1) for k in range(0, x.size, step)]
                          or [np.zeros(0)])


CHORD_SAMPLES = 200_000
"""About the most samples :func:`shortest_chords` looks up in one call to the field (each
costs some 15 float arrays of that size while it is measured: about 25 MB)."""


def shortest_chord(field: DistanceField, x: float, y: float, reach: float = 2.5) -> float:
    """:func:`shortest_chords` of one point (x, y) [m]."""
    return float(shortest_chords(field, [x], [y], reach)[0])


@dataclass(frozen=True)
class Corner:
    """A corner of a route: where (x, y) [m], its ``turn`` [rad], the corridor ``width`` [m]
    there (the narrower leg; in front of the door when the route turns through a ``door``),
    the width ``needed`` [m] at the planner's radius and ``needed_tightest`` [m] at the
    tightest steady radius the joints allow (``tightest_radius`` [m]; inf where no steady
    turn of that radius lines up with the door)."""

    x: float
    y: float
    turn: float
    width: float
    needed: float
    needed_tightest: float
    tightest_radius: float
    band: SweptBand
    door: Door | None = None

    @property
    def too_tight(self) -> bool:
        return self.width < self.needed

    @property
    def what(self) -> str:
        """What blocks here, in a few words (the page's and the picture's label)."""
        spare = "" if self.too_tight else f", {self.width - self.needed:.2f} m to spare"
        if self.door is not None:
            head = ("door the train cannot line up with" if self.too_tight
                    else "door the train barely lines up with")
            return (f"{head} ({self.door.width:.2f} m door, {math.degrees(self.turn):.0f} deg "
                    f"turn{spare}; the corridor in front of it)")
        head = "corner too tight" if self.too_tight else "tight corner"
        return (f"{head} ({math.degrees(self.turn):.0f} deg turn, {self.band.width:.2f} m "
                f"swept{spare})")

    def text(self) -> str:
        band = self.band
        if self.door is not None:
            return self._door_text()
        text = (f"at ({self.x:.2f}, {self.y:.2f}): the route turns "
                f"{math.degrees(self.turn):.0f} deg where the way is {self.width:.2f} m wide "
                "(the narrowest chord across the route within 1.5 m of the corner, or the "
                "widest way through the corner where that is wider); on arcs of the planner's "
                f"radius {band.radius:.2f} m the train sweeps a {band.width:.2f} m band (radii "
                f"{band.r_in:.2f} to {band.r_out:.2f} m, clearances included), so this corner "
                f"needs {self.needed:.2f} m of corridor")
        return text + self._tightest_text(
            f", and {self.needed_tightest:.2f} m even at the tightest steady radius its joints "
            f"allow ({self.tightest_radius:.2f} m)", f"{self.needed_tightest:.2f} m")

    def _tightest_text(self, beyond: str, need: str) -> str:
        """What the tightest steady radius the joints allow changes: ``beyond`` where even it
        needs more than the map has; where only it fits, that it leaves no margin (``need``:
        what it needs, said)."""
        if self.width < self.needed_tightest:
            return beyond
        if self.width < self.needed:
            return (f" (at the tightest steady radius its joints allow, "
                    f"{self.tightest_radius:.2f} m, {need}: a turn that tight leaves no "
                    "margin for the transients)")
        return ""

    def _door_text(self) -> str:
        band, door = self.band, self.door

        def need(width):
            return ("no steady turn of that radius lines up with it" if not math.isfinite(width)
                    else f"{width:.2f} m of corridor in front of it")

        text = (f"to line up with the door at ({door.x:.2f}, {door.y:.2f}) ({door.width:.2f} m "
                f"wide in a {door.wall:.2f} m wall), turning "
                f"{math.degrees(self.turn):.0f} deg into it from a corridor {self.width:.2f} m "
                f"wide: on arcs of the planner's radius {band.radius:.2f} m the train sweeps "
                f"a {band.width:.2f} m band (radii {band.r_in:.2f} to {band.r_out:.2f} m, "
                f"clearances included) and needs {need(self.needed)}")
        return text + self._tightest_text(
            f"; at the tightest steady radius its joints allow ({self.tightest_radius:.2f} m) "
            f"{need(self.needed_tightest)}", need(self.needed_tightest))

    def to_dict(self) -> dict:
        """Plain data (JSON): a need no steady turn meets is None."""
        def finite(v):
            return float(v) if math.isfinite(v) else None

        out = {"x": self.x, "y": self.y, "width": self.width, "needed": finite(self.needed),
               "turn_deg": math.degrees(self.turn), "swept": self.band.width,
               "radius": self.band.radius, "needed_tightest": finite(self.needed_tightest),
               "tightest_radius": self.tightest_radius}
        if self.door is not None:
            out["door"] = {"x": self.door.x, "y": self.door.y, "width": self.door.width,
                           "wall": self.door.wall, "corridor": self.door.corridor}
        return out


def tight_corners(route, field: DistanceField, band: SweptBand, tightest: SweptBand,
                  window: float = 1.0, min_turn: float = math.radians(30.0),
                  only_too_tight: bool = False) -> list[Corner]:
    """The corners of ``route`` (a :class:`~pushtrain.planner.route.Route`): turns of more
    than ``min_turn`` [rad] within ``2 window`` [m], each measured (:class:`Corner`) against
    ``band`` (the planner's radius) and ``tightest`` (the joints' tightest steady radius);
    the tightest corner (the smallest width minus need) first. ``only_too_tight``: leave out
    at once the corners twice the route's distance from the walls shows wide enough (a chord
    through a point is at least twice its distance from the walls)."""
    s, heading = route.s, route.heading
    if route.length < 2.0 * window:
        return []
    ahead = np.interp(s + window, s, heading)
    behind = np.interp(s - window, s, heading)
    turning = np.abs(ahead - behind)
    corners = []
    taken = np.zeros(s.size, dtype=bool)
    for k in np.argsort(-turning, kind="stable"):
        if turning[k] < min_turn:
            break
        if taken[k]:
            continue
        taken |= np.abs(s - s[k]) < 2.0 * window
        sc = float(s[k])
        turn = abs(float(np.interp(sc + 1.5 * window, s, heading)
                         - np.interp(sc - 1.5 * window, s, heading)))
        # the narrowest the legs get within 1.5 windows of the corner: the shortest chord,
        # wall to wall, through the route's points every 5 cm (a door in a thin wall is only
        # a few centimetres of a leg)
        offsets = np.arange(-1.5 * window, 1.5 * window + 1e-9, 0.05)
        door_like = abs(turn - 0.5 * math.pi) <= math.radians(30.0)
        if only_too_tight:
            # between the route's points (d is 1-Lipschitz) and to a sample of the field
            near = np.abs(s - sc) <= 1.5 * window + 1e-9
            spacing = float(np.max(np.diff(s))) if s.size > 1 else 0.0
            lower = 2.0 * (float(route.half_width[near].min()) - 0.5 * spacing
                           - field.resolution)
            if lower >= corner_need(band, turn) and not (
                    door_like and lower < _door_need_at_least(band, lower)):
                continue
        legs = np.array([route.pose_at(sc + ds) for ds in offsets])
        if only_too_tight and not door_like:
            # across the legs only (within 20 deg of their normals), a little farther than
            # the need: widths no smaller than the full measure's, the same where too tight
            across = legs[:, 2:3] + np.radians(np.arange(-20.0, 20.1, 5.0))[None, :]
            widths = chords(field, legs[:, 0], legs[:, 1], across,
                            corner_need(band, turn) + 0.5).min(axis=1)
        else:  # (a door is found, and measured, on the same widths in both modes)
            widths = shortest_chords(field, legs[:, 0], legs[:, 1])
        x, y, _ = route.pose_at(sc)
        door = _door(route, field, sc, offsets, widths) if door_like else None
        if door is not None:  # a door off a corridor: the corridor in front of it decides
            corners.append(Corner(door.x, door.y, min(turn, math.pi), door.corridor,
                                  door_need(band, door.width, door.wall),
                                  door_need(tightest, door.width, door.wall), tightest.radius,
                                  band, door))
            continue
        # a chord cutting a ragged jamb's corner can be narrower than the way there: the
        # corner's width is at least the widest way's through it (within 2 m of it, between
        # the route's points 1.5 windows either side)
        ends = [route.pose_at(sc + ds) for ds in (-1.5 * window, 1.5 * window)]
        local = widest_gap(_crop(field, x, y, 2.0 * window), ends[0], ends[1], 0.0)
        width = max(min(widths), 0.0 if local is None else local.width)
        corners.append(Corner(x, y, min(turn, math.pi), width, corner_need(band, turn),
                              corner_need(tightest, turn), tightest.radius, band))
    corners.sort(key=lambda c: c.width - c.needed)
    return corners
