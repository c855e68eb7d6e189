"""Reeds-Shepp curves: the planner's one home for them.

A Reeds-Shepp path of turning radius ``rho`` is the shortest way between two poses for a
vehicle that drives forward or backward on straight lines and arcs of radius ``rho`` (Reeds and
Shepp, 1990). It is one of 18 *words* of at most five *primitives*: a left arc (L), a straight
line (S) or a right arc (R), each travelled forward (+) or backward (-).

- :func:`shortest_path` computes the word and its primitives' lengths directly from the
  closed-form formulas of Reeds and Shepp (section 8 of the paper), trying the words in the order
  and with the ties that OMPL's ``ReedsSheppStateSpace`` uses, so that the path is the one OMPL
  interpolates (OMPL 2.0.1's Python bindings give the curve's length and interpolation, not its
  word: ``ReedsSheppPathType`` exposes only the length).
- :func:`rs_segments` turns it into the controller's line/arc reference segments;
  :func:`segments_from_states` does so for a path through many states, checked against OMPL.
- OMPL's own space (:func:`reeds_shepp_space`, :class:`ReedsSheppCurve`) serves the search, the
  heuristic's distance and the sampling (:func:`sample_curve_into`).

Planner state: the last trailer's axle midpoint (x, y) and ``yaw`` = its direction of travel
when pushing, yaw = theta + pi (theta: chain heading, toward the robot). Reeds-Shepp "forward"
is therefore pushing (:data:`~pushtrain.core.segment.PUSH`, trailer leads) and "backward"
pulling (:data:`~pushtrain.core.segment.PULL`, robot leads). OMPL's camelCase stays in the
planner's modules that import ompl (this one and :mod:`~pushtrain.planner.ompl_search`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from ompl import base as ob

from pushtrain.core.segment import PULL, PUSH, Segment

__all__ = ["Primitive", "ReedsSheppPath", "shortest_path", "advance_yaw", "evaluate_primitives",
           "primitives_to_segments", "rs_segments", "segments_from_states", "ReedsSheppCurve",
           "reeds_shepp_space", "rs_distance", "sample_curve_into", "travel_between_states",
           "chain_to_planner_state", "planner_yaw", "wrap_yaw"]

log = logging.getLogger(__name__)

_PI = math.pi
_TWO_PI = 2.0 * math.pi
_HALF_PI = 0.5 * math.pi
_ZERO = 10.0 * 2.220446049250313e-16
"""Tolerance of the formulas' sign tests (OMPL's ``ZERO``: ten machine epsilons)."""

_TURN = {"L": 1.0, "S": 0.0, "R": -1.0}

# the 18 words, numbered as in OMPL's ``reedsSheppPathType`` (ties go to the first found)
_WORDS = ("LRL", "RLR", "LRLR", "RLRL", "LRSL", "RLSR", "LSRL", "RSLR", "LRSR", "RLSL", "RSRL",
          "LSLR", "LSR", "RSL", "LSL", "RSR", "LRSLR", "RLSRL")


# ----------------------------------------------------------------------------------------------
# the closed-form words (normalised: rho = 1, start at the origin heading along +x)

def _mod2pi(x: float) -> float:
    """``x`` wrapped into [-pi, pi] (C's fmod, as OMPL)."""
    v = math.fmod(x, _TWO_PI)
    if v < -_PI:
        v += _TWO_PI
    elif v > _PI:
        v -= _TWO_PI
    return v


def _tau_omega(u, v, xi, eta, phi):
    delta = _mod2pi(u - v)
    a = math.sin(u) - math.sin(delta)
    b = math.cos(u) - math.cos(delta) - 1.0
    t1 = math.atan2(eta * a - xi * b, xi * a + eta * b)
    t2 = 2.0 * (math.cos(delta) - math.cos(v) - math.cos(u)) + 3.0
    tau = _mod2pi(t1 + _PI) if t2 < 0 else _mod2pi(t1)
    return tau, _mod2pi(tau - u + v - phi)


def _polar(x, y):
    """(r, angle) of the point (x, y), as OMPL computes them."""
    return math.sqrt(x * x + y * y), math.atan2(y, x)


def _lp_sp_lp(x, y, phi):  # formula 8.1
    u, t = _polar(x - math.sin(phi), y - 1.0 + math.cos(phi))
    if t >= -_ZERO:
        v = _mod2pi(phi - t)
        if v >= -_ZERO:
            return t, u, v
    return None


def _lp_sp_rp(x, y, phi):  # formula 8.2
    r, t1 = _polar(x + math.sin(phi), y - 1.0 - math.cos(phi))
    u1 = r * r
    if u1 >= 4.0:
        u = math.sqrt(u1 - 4.0)
        t = _mod2pi(t1 + math.atan2(2.0, u))
        v = _mod2pi(t - phi)
        if t >= -_ZERO and v >= -_ZERO:
            return t, u, v
    return None


def _lp_rm_l(x, y, phi):  # formula 8.3/8.4 (with the paper's typo corrected, as OMPL)
    u1, theta = _polar(x - math.sin(phi), y - 1.0 + math.cos(phi))
    if u1 <= 4.0:
        u = -2.0 * math.asin(0.25 * u1)
        t = _mod2pi(theta + 0.5 * u + _PI)
        v = _mod2pi(phi - t + u)
        if t >= -_ZERO and u <= _ZERO:
            return t, u, v
    return None


def _lp_rup_lum_rm(x, y, phi):  # formula 8.7
    xi, eta = x + math.sin(phi), y - 1.0 - math.cos(phi)
    rho = 0.25 * (2.0 + math.sqrt(xi * xi + eta * eta))
    if rho <= 1.0:
        u = math.acos(rho)
        t, v = _tau_omega(u, -u, xi, eta, phi)
        if t >= -_ZERO and v <= _ZERO:
            return t, u, v
    return None


def _lp_rum_lum_rp(x, y, phi):  # formula 8.8
    xi, eta = x + math.sin(phi), y - 1.0 - math.cos(phi)
    rho = (20.0 - xi * xi - eta * eta) / 16.0
    if 0.0 <= rho <= 1.0:
        u = -math.acos(rho)
        if u >= -0.5 * _PI:
            t, v = _tau_omega(u, u, xi, eta, phi)
            if t >= -_ZERO and v >= -_ZERO:
                return t, u, v
    return None


def _lp_rm_sm_lm(x, y, phi):  # formula 8.9
    rho, theta = _polar(x - math.sin(phi), y - 1.0 + math.cos(phi))
    if rho >= 2.0:
        r = math.sqrt(rho * rho - 4.0)
        u = 2.0 - r
        t = _mod2pi(theta + math.atan2(r, -2.0))
        v = _mod2pi(phi - 0.5 * _PI - t)
        if t >= -_ZERO and u <= _ZERO and v <= _ZERO:
            return t, u, v
    return None


def _lp_rm_sm_rm(x, y, phi):  # formula 8.10
    xi, eta = x + math.sin(phi), y - 1.0 - math.cos(phi)
    rho, theta = _polar(-eta, xi)
    if rho >= 2.0:
        t = theta
        u = 2.0 - rho
        v = _mod2pi(t + 0.5 * _PI - phi)
        if t >= -_ZERO and u <= _ZERO and v <= _ZERO:
            return t, u, v
    return None


def _lp_rm_s_lm_rp(x, y, phi):  # formula 8.11 (with the paper's typo corrected, as OMPL)
    xi, eta = x + math.sin(phi), y - 1.0 - math.cos(phi)
    rho, _ = _polar(xi, eta)
    if rho >= 2.0:
        u = 4.0 - math.sqrt(rho * rho - 4.0)
        if u <= _ZERO:
            t = _mod2pi(math.atan2((4.0 - u) * xi - 2.0 * eta, -2.0 * xi + (u - 4.0) * eta))
            v = _mod2pi(t - phi)
            if t >= -_ZERO and v >= -_ZERO:
                return t, u, v
    return None


# The symmetries of a formula, in OMPL's order: as is, time-flipped (every length negated),
# reflected (L <-> R: the mirror word), both.
_SYMMETRIES = ((1.0, 1.0, 1.0, False, False), (-1.0, 1.0, -1.0, True, False),
               (1.0, -1.0, -1.0, False, True), (-1.0, -1.0, 1.0, True, True))


def _family(best, lmin, formula, x, y, phi, word, mirror, lengths, double_u=False):
    """Try ``formula`` under the four symmetries; keep a path shorter than ``lmin`` in ``best``
    ([word index, signed normalised lengths]). ``lengths(t, u, v)`` gives the word's pieces.
    Returns the new ``lmin``."""
    for sx, sy, sp, flip, reflect in _SYMMETRIES:
        found = formula(sx * x, sy * y, sp * phi)
        if found is None:
            continue
        t, u, v = found
        length = abs(t) + 2.0 * abs(u) + abs(v) if double_u else abs(t) + abs(u) + abs(v)
        if lmin > length:
            pieces = lengths(t, u, v)
            best[0] = mirror if reflect else word
            best[1] = tuple(-p for p in pieces) if flip else pieces
            lmin = length
    return lmin


def _total(pieces) -> float:
    total = 0.0
    for p in pieces:
        total += abs(p)
    return total


def _normalised_path(x: float, y: float, phi: float):
    """(word index, signed lengths) of the shortest path to (x, y, phi) from the origin for
    rho = 1: lengths are radians on arcs, units of rho on lines; negative: backward."""
    best = [0, (math.inf,)]
    # C S C
    lmin = math.inf
    lmin = _family(best, lmin, _lp_sp_lp, x, y, phi, 14, 15, lambda t, u, v: (t, u, v))
    _family(best, lmin, _lp_sp_rp, x, y, phi, 12, 13, lambda t, u, v: (t, u, v))
    # C C C, forward and backward
    lmin = _total(best[1])
    lmin = _family(best, lmin, _lp_rm_l, x, y, phi, 0, 1, lambda t, u, v: (t, u, v))
    c, s = math.cos(phi), math.sin(phi)
    xb, yb = x * c + y * s, x * s - y * c
    _family(best, lmin, _lp_rm_l, xb, yb, phi, 0, 1, lambda t, u, v: (v, u, t))
    # C C | C C
    lmin = _total(best[1])
    lmin = _family(best, lmin, _lp_rup_lum_rm, x, y, phi, 2, 3,
                   lambda t, u, v: (t, u, -u, v), double_u=True)
    _family(best, lmin, _lp_rum_lum_rp, x, y, phi, 2, 3,
            lambda t, u, v: (t, u, u, v), double_u=True)
    # C C(pi/2) S C and its reverse
    lmin = _total(best[1]) - _HALF_PI
    lmin = _family(best, lmin, _lp_rm_sm_lm, x, y, phi, 4, 5,
                   lambda t, u, v: (t, -_HALF_PI, u, v))
    lmin = _family(best, lmin, _lp_rm_sm_rm, x, y, phi, 8, 9,
                   lambda t, u, v: (t, -_HALF_PI, u, v))
    lmin = _family(best, lmin, _lp_rm_sm_lm, xb, yb, phi, 6, 7,
                   lambda t, u, v: (v, u, -_HALF_PI, t))
    _family(best, lmin, _lp_rm_sm_rm, xb, yb, phi, 10, 11,
            lambda t, u, v: (v, u, -_HALF_PI, t))
    # C C(pi/2) S C(pi/2) C
    lmin = _total(best[1]) - _PI
    _family(best, lmin, _lp_rm_s_lm_rp, x, y, phi, 16, 17,
            lambda t, u, v: (t, -_HALF_PI, u, -_HALF_PI, v))
    return best[0], best[1]


# ----------------------------------------------------------------------------------------------
# paths, primitives and segments

@dataclass(frozen=True)
class Primitive:
    """One piece of a Reeds-Shepp path.

    Parameters
    ----------
    turn : "L", "S" or "R"
        Left arc, straight line, right arc.
    gear : int
        +1 forward (travel along yaw: pushing), -1 backward (pulling).
    length : float
        Distance travelled [m], > 0.
    """

    turn: str
    gear: int
    length: float


@dataclass(frozen=True)
class ReedsSheppPath:
    """The shortest Reeds-Shepp path of radius ``rho`` [m] between two planner states.

    ``word``: its primitives' turns ("LSR", ...); ``lengths``: their signed normalised lengths
    (radians on arcs, units of rho on lines; negative: backward), the pieces OMPL interpolates.
    """

    word: str
    lengths: tuple[float, ...]
    rho: float

    @property
    def length(self) -> float:
        """Length [m]: OMPL's ``ReedsSheppStateSpace.distance`` (rho times the normalised sum)."""
        return self.rho * _total(self.lengths)

    def primitives(self, tol: float = 0.0) -> list[Primitive]:
        """The pieces [m]: those no longer than ``tol`` [m] are left out, and neighbours of the
        same turn and gear merged."""
        out: list[Primitive] = []
        for turn, piece in zip(self.word, self.lengths, strict=False):
            length = abs(piece) * self.rho
            if not length > tol:
                continue
            gear = 1 if piece > 0.0 else -1
            if out and out[-1].turn == turn and out[-1].gear == gear:
                out[-1] = Primitive(turn, gear, out[-1].length + length)
            else:
                out.append(Primitive(turn, gear, length))
        return out


def shortest_path(rho: float, a: Sequence[float], b: Sequence[float]) -> ReedsSheppPath:
    """The shortest Reeds-Shepp path of radius ``rho`` [m] from planner state ``a`` to ``b``
    (x, y, yaw) [m, m, rad], computed as OMPL's ``ReedsSheppStateSpace`` does (yaws wrapped
    into [-pi, pi) as its states hold them). Non-finite input gives an infinite length."""
    yaw_a, yaw_b = wrap_yaw(a[2]), wrap_yaw(b[2])
    dx, dy = float(b[0]) - float(a[0]), float(b[1]) - float(a[1])
    c, s = math.cos(yaw_a), math.sin(yaw_a)
    x, y = c * dx + s * dy, -s * dx + c * dy
    word, lengths = _normalised_path(x / rho, y / rho, yaw_b - yaw_a)
    if not math.isfinite(lengths[0]):
        return ReedsSheppPath("L", (math.inf,), float(rho))
    return ReedsSheppPath(_WORDS[word], lengths, float(rho))


def advance_yaw(x: float, y: float, yaw: float, turn: str, gear: int, dist, rho: float):
    """Pose after travelling ``dist`` [m] (scalar or array) on a primitive of radius ``rho`` [m].

    Same formulas as OMPL's ``ReedsSheppStateSpace::interpolate`` (scaled by rho).
    """
    k = _TURN[turn]
    if isinstance(dist, float):
        v = gear * dist / rho
        if k == 0.0:
            return x + rho * v * math.cos(yaw), y + rho * v * math.sin(yaw), yaw
        phi = yaw + k * v
        return (x + rho * k * (math.sin(phi) - math.sin(yaw)),
                y - rho * k * (math.cos(phi) - math.cos(yaw)), phi)
    dist = np.asarray(dist, dtype=float)
    v = gear * dist / rho  # signed normalized length
    if k == 0.0:
        return x + rho * v * math.cos(yaw), y + rho * v * math.sin(yaw), yaw + 0.0 * v
    phi = yaw + k * v
    return (
        x + rho * k * (np.sin(phi) - math.sin(yaw)),
        y - rho * k * (np.cos(phi) - math.cos(yaw)),
        phi,
    )


def evaluate_primitives(start, primitives, rho: float, s) -> np.ndarray:
    """Poses (x, y, yaw) [m, m, rad] at travelled distances ``s`` [m] along the primitives.

    Independent of OMPL. Shape (len(s), 3); yaw is continuous.
    """
    s = np.atleast_1d(np.asarray(s, dtype=float))
    out = np.empty((s.size, 3))
    pose = tuple(map(float, start))
    s0 = 0.0
    bounds = np.cumsum([p.length for p in primitives])
    for k, prim in enumerate(primitives):
        last = k == len(primitives) - 1
        mask = (s >= s0) & ((s <= bounds[k]) if last else (s < bounds[k]))
        x, y, yaw = advance_yaw(*pose, prim.turn, prim.gear, s[mask] - s0, rho)
        out[mask] = np.column_stack([x, y, yaw])
        x, y, yaw = advance_yaw(*pose, prim.turn, prim.gear, prim.length, rho)
        pose, s0 = (float(x), float(y), float(yaw)), float(bounds[k])
    if primitives:
        out[s > bounds[-1]] = pose
        out[s < 0.0] = tuple(map(float, start))
    else:
        out[:] = tuple(map(float, start))
    return out


def primitives_to_segments(primitives: Sequence[Primitive], rho: float) -> list[Segment]:
    """Planner-frame primitives -> reference segments (forward = PUSH, backward = PULL).

    The chain heading theta = yaw + pi changes like yaw, so d(theta)/ds per metre travelled is
    +1/rho for a left arc driven forward, -1/rho backward, and the opposite for right arcs.
    """
    out = []
    for p in primitives:
        direction = PUSH if p.gear > 0 else PULL
        if p.turn == "S":
            out.append(Segment("line", p.length, 0.0, direction))
        else:
            k = (1.0 if p.turn == "L" else -1.0) * p.gear / rho
            out.append(Segment("arc", p.length, k, direction))
    return out


def rs_segments(pose, goal, radius: float) -> list[Segment] | None:
    """The shortest Reeds-Shepp path of ``radius`` [m] from ``pose`` to ``goal`` (chain
    convention) as reference segments (forward = pushing; pieces under a micrometre left out);
    None for non-finite poses (logged; the caller goes without this connection)."""
    path = shortest_path(radius, chain_to_planner_state(pose), chain_to_planner_state(goal))
    if not math.isfinite(path.length):
        log.warning("no Reeds-Shepp connection from %s to %s", tuple(pose), tuple(goal))
        return None
    if path.length < 1e-6:
        return []
    segments = primitives_to_segments(path.primitives(tol=1e-7), radius)
    return [g for g in segments if g.length > 1e-6]


def _merge(segments: Sequence[Segment]) -> list[Segment]:
    out: list[Segment] = []
    for g in segments:
        if out and (out[-1].kind, out[-1].curvature, out[-1].direction) == (
            g.kind, g.curvature, g.direction
        ):
            out[-1] = Segment(g.kind, out[-1].length + g.length, g.curvature, g.direction)
        else:
            out.append(g)
    return out


def segments_from_states(states: np.ndarray, rho: float) -> tuple[list[Segment], float]:
    """Line/arc segments of the Reeds-Shepp path through ``states`` (planner frame), and the
    largest deviation [m] between the segments and OMPL's interpolation (checked at 33 points
    per local curve)."""
    prims: list[Primitive] = []
    worst = 0.0
    ts = np.linspace(0.0, 1.0, 33)
    for a, b in zip(states[:-1], states[1:], strict=True):
        path = shortest_path(rho, a, b)
        p = path.primitives(tol=1e-9)
        if path.length > 0.0 and p:
            curve = ReedsSheppCurve(rho, a, b)
            ref = np.array([curve.interpolate(t) for t in ts])
            ev = evaluate_primitives(a, p, rho, ts * curve.length)
            worst = max(worst, float(np.hypot(*(ev[:, :2] - ref[:, :2]).T).max()))
        prims += p
    return _merge(primitives_to_segments(prims, rho)), worst


# ----------------------------------------------------------------------------------------------
# OMPL's Reeds-Shepp space: the search's distance, interpolation and sampling

def reeds_shepp_space(rho: float, bounds) -> ob.ReedsSheppStateSpace:
    """OMPL's Reeds-Shepp space of radius ``rho`` [m] on ``bounds`` (xmin, ymin, xmax, ymax)."""
    space = ob.ReedsSheppStateSpace(float(rho))
    b = ob.RealVectorBounds(2)
    b.setLow(0, bounds[0])
    b.setLow(1, bounds[1])
    b.setHigh(0, bounds[2])
    b.setHigh(1, bounds[3])
    space.setBounds(b)
    return space


def wrap_yaw(yaw: float) -> float:
    """Yaw in [-pi, pi) as OMPL's SO2 bounds require."""
    return (float(yaw) + math.pi) % (2.0 * math.pi) - math.pi


def planner_yaw(theta: float) -> float:
    """Chain heading theta -> the planner state's yaw (theta + pi) in [-pi, pi), as OMPL's SO2
    state holds it (``wrap_yaw(theta + pi)`` up to rounding)."""
    return (float(theta) + 2.0 * math.pi) % (2.0 * math.pi) - math.pi


def chain_to_planner_state(pose) -> tuple[float, float, float]:
    """Chain pose (x, y, theta) -> planner state (x, y, yaw = theta + pi)."""
    return float(pose[0]), float(pose[1]), float(pose[2]) + math.pi


class ReedsSheppCurve:
    """OMPL's Reeds-Shepp curve between two planner states (x, y, yaw) for radius ``rho``.

    ``length`` is OMPL's ``distance`` [m]; :meth:`interpolate` is OMPL's ``interpolate`` at
    the fraction t in [0, 1]. (Its pieces: :func:`shortest_path`.)
    """

    def __init__(self, rho: float, a: Sequence[float], b: Sequence[float]):
        pad = 2.0 * rho + 1.0
        lo = min(a[0], b[0]) - pad, min(a[1], b[1]) - pad
        hi = max(a[0], b[0]) + pad, max(a[1], b[1]) + pad
        self.rho = float(rho)
        self._space = reeds_shepp_space(rho, (lo[0], lo[1], hi[0], hi[1]))
        self._a, self._b, self._out = (self._space.allocState() for _ in range(3))
        for state, pose in ((self._a, a), (self._b, b)):
            state.setX(float(pose[0]))
            state.setY(float(pose[1]))
            state.setYaw(wrap_yaw(pose[2]))
        self.length = float(self._space.distance(self._a, self._b))

    def interpolate(self, t: float) -> tuple[float, float, float]:
        """Pose (x, y, yaw) at the fraction ``t`` of the curve."""
        self._space.interpolate(self._a, self._b, float(t), self._out)
        return self._out.getX(), self._out.getY(), self._out.getYaw()


def rs_distance(rho: float, a: Sequence[float], b: Sequence[float]) -> float:
    """Length [m] of the shortest Reeds-Shepp curve from pose ``a`` to ``b`` (x, y, yaw), by
    OMPL."""
    return ReedsSheppCurve(rho, a, b).length


def sample_curve_into(rows: list, space, a, b, m: int, tmp) -> None:
    """Append to ``rows`` the states (x, y, yaw) of OMPL's curve ``a -> b`` at the fractions
    k/m, k = 1..m (``tmp``: a scratch state of ``space``)."""
    interpolate, get_x, get_y, get_yaw = space.interpolate, tmp.getX, tmp.getY, tmp.getYaw
    for k in range(1, m + 1):
        interpolate(a, b, k / m, tmp)
        rows.append((get_x(), get_y(), get_yaw()))


def travel_between_states(pts: np.ndarray):
    """Travel between consecutive planner states ``pts`` (K, 3) = (x, y, yaw): whether each step
    k -> k+1 goes backward (against the yaw at its middle), its yaw change [rad] and its
    length [m], each (K-1,)."""
    dyaw = (np.diff(pts[:, 2]) + math.pi) % (2.0 * math.pi) - math.pi
    mid = pts[:-1, 2] + 0.5 * dyaw
    d = np.diff(pts[:, :2], axis=0)
    backward = d[:, 0] * np.cos(mid) + d[:, 1] * np.sin(mid) < 0.0
    return backward, dyaw, np.hypot(d[:, 0], d[:, 1])
