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
    counts).

Lengths in metres, angles in radians. Node (i, j) of a
:class:`~pushtrain.facility.distance_field.DistanceField` is at ``(x0 + j h, y0 + i h)``.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np
from scipy import ndimage  # at import (0.1-0.3 s once), not in the first search

from pushtrain.facility.distance_field import DistanceField

__all__ = ["Bottleneck", "widest_gap", "passable", "needed_half_width", "SweptBand",
           "swept_band", "corner_need", "Corner", "tight_corners", "width_across",
           "shortest_chord"]

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
    r_in, r_out = math.inf, 0.0
    for i, body in enumerate(train.bodies):
        m = float(margins[i])
        along = abs(body.offset) + 0.5 * body.length
        r_out = max(r_out, math.hypot(rho[i] + 0.5 * body.width, along) + m)
        r_in = min(r_in, rho[i] - 0.5 * body.width - m)
    return SweptBand(float(radius), max(r_in, 0.0), r_out)


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
    ``2 reach``."""
    return chords(field, x, y, CHORD_DIRECTIONS, reach).min(axis=1)


def shortest_chord(field: DistanceField, x: float, y: float, reach: float = 2.5) -> float:
    """:func:`shortest_chords` of one point (x, y) [m]."""
    return float(shortest_chords(field, [x], [y], reach)[0])


@dataclass(frozen=True)
class Corner:
    """A corner of a route: where (x, y) [m], its ``turn`` [rad], the corridor ``width`` [m]
    there (the narrower leg), the width ``needed`` [m] at the planner's radius and
    ``needed_tightest`` [m] at the tightest steady radius the joints allow
    (``tightest_radius`` [m])."""

    x: float
    y: float
    turn: float
    width: float
    needed: float
    needed_tightest: float
    tightest_radius: float
    band: SweptBand

    @property
    def too_tight(self) -> bool:
        return self.width < self.needed

    def text(self) -> str:
        band = self.band
        text = (f"at ({self.x:.2f}, {self.y:.2f}): the route turns "
                f"{math.degrees(self.turn):.0f} deg where the way is {self.width:.2f} m wide "
                f"(its narrowest within 1.5 m of the corner); on arcs of the planner's radius "
                f"{band.radius:.2f} m the train sweeps a {band.width:.2f} m band (radii "
                f"{band.r_in:.2f} to {band.r_out:.2f} m, clearances included), so this corner "
                f"needs {self.needed:.2f} m of corridor")
        if self.width < self.needed_tightest:
            text += (f", and {self.needed_tightest:.2f} m even at the tightest steady radius "
                     f"its joints allow ({self.tightest_radius:.2f} m)")
        elif self.width < self.needed:
            text += (f" (at the tightest steady radius its joints allow, "
                     f"{self.tightest_radius:.2f} m, {self.needed_tightest:.2f} m: "
                     "a turn that tight leaves no margin for the transients)")
        return text

    def to_dict(self) -> dict:
        return {"x": self.x, "y": self.y, "width": self.width, "needed": self.needed,
                "turn_deg": math.degrees(self.turn), "swept": self.band.width,
                "radius": self.band.radius, "needed_tightest": self.needed_tightest,
                "tightest_radius": self.tightest_radius}


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
        if only_too_tight:
            # between the route's points (d is 1-Lipschitz) and to a sample of the field
            near = np.abs(s - sc) <= 1.5 * window + 1e-9
            spacing = float(np.max(np.diff(s))) if s.size > 1 else 0.0
            lower = 2.0 * (float(route.half_width[near].min()) - 0.5 * spacing
                           - field.resolution)
            if lower >= corner_need(band, turn):
                continue
        legs = np.array([route.pose_at(sc + ds)
                         for ds in np.arange(-1.5 * window, 1.5 * window + 1e-9, 0.05)])
        if only_too_tight:
            # across the legs only (within 20 deg of their normals), as far as the need: a
            # width no smaller than the full measure's, the same wherever it is too tight
            need = corner_need(band, turn)
            across = legs[:, 2:3] + np.radians(np.arange(-20.0, 20.1, 5.0))[None, :]
            width = float(chords(field, legs[:, 0], legs[:, 1], across, need).min())
        else:
            width = float(shortest_chords(field, legs[:, 0], legs[:, 1]).min())
        x, y, _ = route.pose_at(sc)
        corners.append(Corner(x, y, min(turn, math.pi), width, corner_need(band, turn),
                              corner_need(tightest, turn), tightest.radius, band))
    corners.sort(key=lambda c: c.width - c.needed)
    return corners
