"""The whole train against a distance field: clearance of every body, joint limits, self-collision.

The planner's search asks, for every simulated state of the train along a candidate motion,
whether each body keeps its clearance from the walls. It asks the map's signed distance field
(:meth:`~pushtrain.facility.free_space.World.distance_field`, the same call on polygon maps and on
occupancy grids) at sample points of each body's rectangle, fixed in the body's frame once
(:func:`body_samples`), with a threshold per point that makes the sampled test conservative:

Perimeter points
    Spaced at most ``spacing`` along every edge (corners included). The signed distance d is
    1-Lipschitz, so a point of an edge within ``s/2`` of a sample whose value is ``d`` has at
    least ``d - s/2``; an edge keeps ``margin`` if every sample keeps ``margin + s/2 + tol``
    (``tol``: the field's own interpolation error, about a millimetre at the margins of a 2 cm
    polygon field; see :mod:`~pushtrain.facility.distance_field`).
Interior points
    An obstacle smaller than the body (a pillar, a few occupied cells) can lie wholly inside the
    rectangle while every perimeter sample is clear. The perimeter samples, once accepted,
    certify discs of radius ``margin + s/2 + tol`` around them, i.e. a band of depth at least
    ``b = sqrt(m'^2 + m' s)`` (``m' = margin + tol``) inside the edges. The rest of the
    rectangle is tiled by cells of at most ``interior`` metres; a cell is free if its centre's
    distance is at least the half-diagonal of the cell. So the whole rectangle is free and keeps
    ``margin`` when every sample passes its threshold, and in a corridor the interior thresholds
    (about 0.1 m) never bind: a cell centre lies ``b`` + half a cell inside the edges.

Joint angles are tested against ``phi_limit`` (|phi_i| <= limit for every joint) and bodies that
are not neighbours in the chain (i and j >= i + 2) against overlapping each other (separating
axis test of the two rectangles): a train folded on itself is a collision the walls never see.

Arrays are vectorized over the samples of a trajectory (K states). Units: metres, radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pushtrain.core.kinematics import body_positions
from pushtrain.facility.distance_field import DistanceField

from .train import BodyFootprint, Train

__all__ = ["BodySamples", "body_samples", "disc_cover", "first_failure",
           "FIELD_TOLERANCE", "body_name", "self_overlap"]

FIELD_TOLERANCE = 0.002
"""Allowance [m] for the distance field's interpolation error at clearance distances (bilinear
between exact nodes: below 1 mm at 5 cm from a convex wall corner on the 2 cm grid)."""


def body_name(i: int) -> str:
    """"robot" for body 0, "trailer i" else."""
    return "robot" if i == 0 else f"trailer {i}"


@dataclass(frozen=True)
class BodySamples:
    """Sample points of every body in its own frame and the distance each must keep.

    Attributes
    ----------
    body : (P,) int array
        Body index (0 robot .. n) of each point.
    u, v : (P,) arrays
        Point along the heading (toward the robot) and to the left, from the body's axle
        midpoint [m].
    threshold : (P,) array
        Smallest signed distance [m] the field may have at the point.
    radius : (n+1,) array
        Radius [m] of the smallest circle about each body's axle midpoint that holds its
        rectangle.
    slack : (n+1,) array
        The quick test: a body whose axle midpoint has a distance of at least ``slack[i]``
        (that radius plus its perimeter threshold) keeps its clearance everywhere (d is
        1-Lipschitz), and its points are not looked up.
    margins : (n+1,) array
        The clearance [m] each body keeps (what the thresholds were built from).
    """

    body: np.ndarray
    u: np.ndarray
    v: np.ndarray
    threshold: np.ndarray
    radius: np.ndarray
    slack: np.ndarray
    margins: np.ndarray

    @property
    def n_bodies(self) -> int:
        return int(self.radius.size)


def _perimeter(fp: BodyFootprint, spacing: float):
    """Points (u, v) along the rectangle's edges, at most ``spacing`` apart, corners included,
    and the largest spacing used."""
    hl, hw = 0.5 * fp.length, 0.5 * fp.width
    corners = [(fp.offset + hl, hw), (fp.offset - hl, hw), (fp.offset - hl, -hw),
               (fp.offset + hl, -hw)]
    us, vs, worst = [], [], 0.0
    for (ua, va), (ub, vb) in zip(corners, corners[1:] + corners[:1], strict=True):
        length = math.hypot(ub - ua, vb - va)
        m = max(1, int(math.ceil(length / spacing - 1e-9)))
        worst = max(worst, length / m)
        f = np.arange(m) / m
        us.append(ua + f * (ub - ua))
        vs.append(va + f * (vb - va))
    return np.concatenate(us), np.concatenate(vs), worst


def _interior(fp: BodyFootprint, band: float, cell: float):
    """Centres (u, v) of cells of at most ``cell`` metres tiling the rectangle shrunk by
    ``band``, and the cells' half-diagonal (the distance each centre must keep)."""
    lu = fp.length - 2.0 * band
    lv = fp.width - 2.0 * band
    if lu <= 0.0 or lv <= 0.0:
        return np.zeros(0), np.zeros(0), 0.0
    nu = max(1, int(math.ceil(lu / cell - 1e-9)))
    nv = max(1, int(math.ceil(lv / cell - 1e-9)))
    du, dv = lu / nu, lv / nv
    uu = fp.offset - 0.5 * lu + du * (np.arange(nu) + 0.5)
    vv = -0.5 * lv + dv * (np.arange(nv) + 0.5)
    gu, gv = np.meshgrid(uu, vv, indexing="ij")
    return gu.ravel(), gv.ravel(), 0.5 * math.hypot(du, dv)


def body_samples(train: Train, margins, spacing: float = 0.025, interior: float = 0.15,
                 tolerance: float = FIELD_TOLERANCE) -> BodySamples:
    """The sample points and thresholds of every body (see the module docstring).

    Parameters
    ----------
    train : Train
    margins : float or (n+1,) sequence
        Clearance [m] of each body (robot first), >= 0.
    spacing : float
        Largest distance [m] between perimeter samples (the test is conservative by half of it).
    interior : float
        Largest interior cell [m].
    tolerance : float
        Allowance [m] for the field's interpolation error.
    """
    n1 = train.n + 1
    margins = np.broadcast_to(np.asarray(margins, dtype=float), (n1,)).copy()
    body, us, vs, thr, radius, slack = [], [], [], [], [], []
    for i, fp in enumerate(train.bodies):
        pu, pv, s = _perimeter(fp, spacing)
        m_eff = margins[i] + tolerance
        t_perim = margins[i] + 0.5 * s + tolerance
        band = math.sqrt(m_eff * m_eff + m_eff * s)
        iu, iv, t_in = _interior(fp, band, interior)
        body.append(np.full(pu.size + iu.size, i))
        us += [pu, iu]
        vs += [pv, iv]
        thr += [np.full(pu.size, t_perim), np.full(iu.size, t_in)]
        r = math.hypot(abs(fp.offset) + 0.5 * fp.length, 0.5 * fp.width)
        radius.append(r)
        slack.append(r + t_perim)
    return BodySamples(np.concatenate(body), np.concatenate(us), np.concatenate(vs),
                       np.concatenate(thr), np.array(radius), np.array(slack), margins)


def _wall_failure(field: DistanceField, samples: BodySamples, x, y, th, covers=None):
    """First state (index) where some body misses its clearance, as (k, body, x, y, distance,
    threshold) of the worst point, or None; and the motion's reserve: the smallest excess
    [m] of a sample over its threshold (bodies that pass the quick test count with the excess
    of their midpoint over :attr:`BodySamples.slack`). ``x, y, th`` are (K, n+1)."""
    centre = field.at(x, y)  # (K, n+1)
    excess_centre = centre - samples.slack[None, :]
    need = np.argwhere(excess_centre < 0.0)  # (M, 2): state, body
    clear = excess_centre[excess_centre >= 0.0]
    reserve = float(clear.min()) if clear.size else math.inf
    failure = None
    ks, bs = need[:, 0], need[:, 1]
    for i in np.unique(bs):
        rows = ks[bs == i]
        sel = samples.body == i
        u, v, thr = samples.u[sel], samples.v[sel], samples.threshold[sel]
        c, s = np.cos(th[rows, i])[:, None], np.sin(th[rows, i])[:, None]
        px = x[rows, i][:, None] + u[None, :] * c - v[None, :] * s
        py = y[rows, i][:, None] + u[None, :] * s + v[None, :] * c
        d = field.at(px, py)
        excess = d - thr[None, :]
        lowest = excess.min(axis=1)
        reserve = min(reserve, float(lowest.min()))
        bad = np.flatnonzero(lowest < 0.0)
        if bad.size and covers is not None:
            centres, threshold = covers[i]
            cu, cv = centres[None, :, 0], centres[None, :, 1]
            cx = x[rows[bad], i][:, None] + cu * c[bad] - cv * s[bad]
            cy = y[rows[bad], i][:, None] + cu * s[bad] + cv * c[bad]
            bad = bad[~(field.at(cx, cy) >= threshold).all(axis=1)]
        if bad.size:
            r = int(bad[0])
            j = int(np.argmin(excess[r]))
            cand = (int(rows[r]), int(i), float(px[r, j]), float(py[r, j]), float(d[r, j]),
                    float(thr[j]))
            if failure is None or cand[0] < failure[0]:
                failure = cand
    return failure, reserve


def disc_cover(body: BodyFootprint, cell: float):
    """Centres (m, 2) [m] of discs that cover ``body``'s rectangle (one per cell of a grid of
    cells at most ``cell`` metres) and their radius [m] (the cells' half diagonal): a body whose
    disc centres all keep ``margin + radius`` keeps ``margin`` everywhere, its inside included."""
    nu = max(1, int(math.ceil(body.length / cell - 1e-9)))
    nv = max(1, int(math.ceil(body.width / cell - 1e-9)))
    du, dv = body.length / nu, body.width / nv
    u = body.offset - 0.5 * body.length + du * (np.arange(nu) + 0.5)
    v = -0.5 * body.width + dv * (np.arange(nv) + 0.5)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    return np.column_stack([uu.ravel(), vv.ravel()]), 0.5 * math.hypot(du, dv)


def self_overlap(train: Train, x, y, th):
    """First state where two bodies i, j >= i + 2 overlap (separating-axis test of the two
    rectangles), as (k, i, j, x, y) with the midpoint of their centres, or None."""
    n1 = x.shape[1]
    bodies = train.bodies
    first = None
    for i in range(n1 - 2):
        for j in range(i + 2, n1):
            a, b = bodies[i], bodies[j]
            ra = math.hypot(abs(a.offset) + 0.5 * a.length, 0.5 * a.width)
            rb = math.hypot(abs(b.offset) + 0.5 * b.length, 0.5 * b.width)
            dx = x[:, j] - x[:, i]
            dy = y[:, j] - y[:, i]
            near = np.flatnonzero(dx * dx + dy * dy <= (ra + rb) ** 2)
            if not near.size:
                continue
            hit = _obb_overlap(a, b, x[near, i], y[near, i], th[near, i], x[near, j],
                               y[near, j], th[near, j])
            if hit.any():
                k = int(near[np.flatnonzero(hit)[0]])
                if first is None or k < first[0]:
                    first = (k, i, j, 0.5 * float(x[k, i] + x[k, j]),
                             0.5 * float(y[k, i] + y[k, j]))
    return first


def _obb_overlap(a: BodyFootprint, b: BodyFootprint, xa, ya, tha, xb, yb, thb) -> np.ndarray:
    """Whether rectangles a at (xa, ya, tha) and b at (xb, yb, thb) overlap (arrays)."""
    ca, sa = np.cos(tha), np.sin(tha)
    cb, sb = np.cos(thb), np.sin(thb)
    # rectangle centres
    pax, pay = xa + a.offset * ca, ya + a.offset * sa
    pbx, pby = xb + b.offset * cb, yb + b.offset * sb
    dx, dy = pbx - pax, pby - pay
    sep = np.zeros(np.shape(xa), dtype=bool)
    axes = ((ca, sa), (-sa, ca), (cb, sb), (-sb, cb))
    for ux, uy in axes:
        # projections of both rectangles' half extents on the axis
        ra = (0.5 * a.length * np.abs(ca * ux + sa * uy)
              + 0.5 * a.width * np.abs(-sa * ux + ca * uy))
        rb = (0.5 * b.length * np.abs(cb * ux + sb * uy)
              + 0.5 * b.width * np.abs(-sb * ux + cb * uy))
        sep |= np.abs(dx * ux + dy * uy) > ra + rb
    return ~sep


def first_failure(train: Train, field: DistanceField, samples: BodySamples, z: np.ndarray,
                  phi_limit: float, covers=None):
    """The first failure of the train states ``z`` (K, 3 + n), or None, and the motion's
    clearance reserve [m] (smallest distance of a body beyond its margin, approximate).

    A failure is a dict: ``kind`` ("collision", "joint_limit" or "self_collision"), ``k`` (state
    index), ``body``, ``x``, ``y`` (the point that misses its clearance, the joint's trailer, or
    between the two bodies), and ``distance``/``threshold`` [m], ``phi`` [rad] or ``other``
    (the second body). ``covers``: per body (disc centres (m, 2) in its frame, threshold [m])
    of :func:`disc_cover`; a body whose disc centres all keep the threshold at a state passes
    there whatever its sample points say (None: the samples alone decide).
    """
    x, y = body_positions(z[:, 0], z[:, 1], z[:, 2:], train.geometry)
    th = z[:, 2:]
    phi = th[:, :-1] - th[:, 1:]
    phi = (phi + math.pi) % (2.0 * math.pi) - math.pi
    over = np.flatnonzero((np.abs(phi) > phi_limit).any(axis=1))
    candidates = []
    if over.size:
        k = int(over[0])
        j = int(np.argmax(np.abs(phi[k])))
        candidates.append({"kind": "joint_limit", "k": k, "body": j + 1,
                           "x": float(x[k, j + 1]), "y": float(y[k, j + 1]),
                           "phi": float(phi[k, j])})
    wall, reserve = _wall_failure(field, samples, x, y, th, covers)
    if wall is not None:
        k, i, px, py, d, thr = wall
        candidates.append({"kind": "collision", "k": k, "body": i, "x": px, "y": py,
                           "distance": d, "threshold": thr,
                           "margin": float(samples.margins[i])})
    selfhit = self_overlap(train, x, y, th)
    if selfhit is not None:
        k, i, j, px, py = selfhit
        candidates.append({"kind": "self_collision", "k": k, "body": i, "other": j, "x": px,
                           "y": py})
    if not candidates:
        return None, reserve
    return min(candidates, key=lambda f: f["k"]), reserve
