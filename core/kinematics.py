"""Chain kinematics of a robot with n off-hooked trailers (numpy; the bodies' positions are the
engine's C, :func:`body_positions`).

Conventions (the paper's, except that headings are measured from +x: its Eq. (1) measures them
from +y, while its Eq. (2)-(5) and (14) need +x): body 0 is the robot, bodies 1..n the trailers.
Heading ``theta[i]`` is measured from +x, CCW positive, and points toward the robot (the towing
direction), so a straight chain has equal headings and pushing has ``v[i] < 0``. Unit vectors
``e_i = (cos theta_i, sin theta_i)`` and left normal ``n_i = (-sin theta_i, cos theta_i)``.
Joint angle ``phi[i] = theta[i-1] - theta[i]`` (i = 1..n).

Off-hooked hitch: the rear hitch of body i-1 at ``P_{i-1} - R_{i-1} e_{i-1}`` coincides with the
front hitch of trailer i at ``P_i + F_i e_i``. ``front[k]`` holds F_{k+1} (k = 0..n-1) and
``rear[k]`` holds R_k (k = 0..n-1), both in metres.

Rolling without lateral slip at each axle midpoint gives, with c = cos phi_i, s = sin phi_i::

    v_i = c v_{i-1} + R_{i-1} s w_{i-1}
    w_i = (s v_{i-1} - R_{i-1} c w_{i-1}) / F_i

and its inverse (from trailer i back to body i-1)::

    v_{i-1} = c v_i + F_i s w_i
    w_{i-1} = (s v_i - F_i c w_i) / R_{i-1}

For D = F = R the 2x2 map M(phi) = [[c, D s], [s/D, -c]] is its own inverse and composing the
inverses from trailer n to the robot is the paper's Eq. (5).
"""

from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass
from math import cos, sin

import numpy as np

from pushtrain.table1 import LINK

from . import native

__all__ = [
    "ChainGeometry",
    "wrap_angle",
    "wrap_scalar",
    "joint_angles",
    "forward_velocities",
    "inverse_velocities",
    "body_positions",
    "robot_velocity_from_last",
    "velocities_from_last",
    "heading_rates_from_robot",
    "heading_rates_from_last",
    "steady_joint_angle",
    "eq5_matrix",
]


def wrap_angle(angle):
    """Wrap angles [rad] to (-pi, pi]."""
    wrapped = np.mod(np.asarray(angle, dtype=float) + np.pi, 2.0 * np.pi) - np.pi
    wrapped = np.where(wrapped == -np.pi, np.pi, wrapped)
    return wrapped if np.ndim(wrapped) else float(wrapped)


def wrap_scalar(angle: float) -> float:
    """Wrap one angle [rad] to (-pi, pi] with plain floats (for per-step loops)."""
    wrapped = (angle + math.pi) % (2.0 * math.pi) - math.pi
    return math.pi if wrapped == -math.pi else wrapped


@dataclass(frozen=True)
class ChainGeometry:
    """Hitch link lengths of an n-trailer chain [m].

    Parameters
    ----------
    front : array of shape (n,)
        F_1..F_n, distance from trailer i's axle midpoint forward to its hitch point.
    rear : array of shape (n,)
        R_0..R_{n-1}, distance from body k's centre back to its rear hitch point.
    """

    front: np.ndarray
    rear: np.ndarray

    def __post_init__(self):
        front = np.asarray(self.front, dtype=float).reshape(-1)
        rear = np.asarray(self.rear, dtype=float).reshape(-1)
        if front.shape != rear.shape or front.size < 1:
            raise ValueError(
                f"front and rear must both have n >= 1 entries; got {front.size} and {rear.size}"
            )
        for name, values in (("front", front), ("rear", rear)):
            bad = np.flatnonzero(~(values > 0.0) | ~np.isfinite(values))
            if bad.size:
                k = int(bad[0])
                raise ValueError(
                    f"{name}[{k}] = {values[k]!r} m: link lengths must be finite and > 0"
                )
        object.__setattr__(self, "front", front)
        object.__setattr__(self, "rear", rear)

    @classmethod
    def uniform(cls, n_trailers: int, link: float = LINK) -> "ChainGeometry":
        """A chain of ``n_trailers`` with every F_i = R_i = ``link`` [m] (the paper's D)."""
        if int(n_trailers) < 1:
            raise ValueError(f"n_trailers = {n_trailers!r}: need at least 1 trailer")
        return cls(np.full(int(n_trailers), float(link)), np.full(int(n_trailers), float(link)))

    @property
    def n(self) -> int:
        """Number of trailers."""
        return int(self.front.size)


def joint_angles(theta) -> np.ndarray:
    """Joint angles phi_i = theta_{i-1} - theta_i, wrapped to (-pi, pi], shape (n,) [rad]."""
    theta = np.asarray(theta, dtype=float)
    return np.asarray(wrap_angle(theta[..., :-1] - theta[..., 1:]))


def forward_velocities(phi, v0: float, w0: float, geom: ChainGeometry):
    """Velocities of every body from the robot's (v0 [m/s], w0 [rad/s]).

    Returns ``(v, w)``, each of shape (n+1,): longitudinal speed [m/s] and yaw rate [rad/s].
    """
    phi = np.asarray(phi, dtype=float)
    n = geom.n
    v = np.empty(n + 1)
    w = np.empty(n + 1)
    v[0], w[0] = v0, w0
    c, s = np.cos(phi), np.sin(phi)
    for i in range(1, n + 1):
        r = geom.rear[i - 1]
        v[i] = c[i - 1] * v[i - 1] + r * s[i - 1] * w[i - 1]
        w[i] = (s[i - 1] * v[i - 1] - r * c[i - 1] * w[i - 1]) / geom.front[i - 1]
    return v, w


def inverse_velocities(phi, v_n: float, w_n: float, geom: ChainGeometry):
    """Velocities of every body that make the last trailer move with (v_n, w_n).

    This is Step 3 of the paper (Eq. 5 for D = F = R) for general links. Returns ``(v, w)``,
    each of shape (n+1,); ``v[0], w[0]`` are the robot commands [m/s, rad/s].
    """
    phi = np.asarray(phi, dtype=float)
    n = geom.n
    v = np.empty(n + 1)
    w = np.empty(n + 1)
    v[n], w[n] = v_n, w_n
    c, s = np.cos(phi), np.sin(phi)
    for i in range(n, 0, -1):
        f = geom.front[i - 1]
        v[i - 1] = c[i - 1] * v[i] + f * s[i - 1] * w[i]
        w[i - 1] = (s[i - 1] * v[i] - f * c[i - 1] * w[i]) / geom.rear[i - 1]
    return v, w


def heading_rates_from_robot(theta, v0: float, w0: float, geom: ChainGeometry) -> np.ndarray:
    """d(theta)/dt of every body [rad/s] when the robot moves with (v0, w0)."""
    return forward_velocities(joint_angles(theta), v0, w0, geom)[1]


def heading_rates_from_last(theta, v_n: float, w_n: float, geom: ChainGeometry) -> np.ndarray:
    """d(theta)/dt of every body [rad/s] when the last trailer moves with (v_n, w_n)."""
    return inverse_velocities(joint_angles(theta), v_n, w_n, geom)[1]


def body_positions(x, y, headings, geometry: ChainGeometry, from_last: bool = False):
    """Axle-midpoint positions [m] of every body from one body's position and all headings.

    ``P_i = P_{i-1} - R_{i-1} e_{i-1} - F_i e_i``, each body's offset from the anchor summed
    link by link outward from it and added to the anchor's position: the one definition,
    ``pt_chain_positions`` in ``core/csrc/control.c`` (the engine's checks, the pull guide and
    the controller's estimate of the last trailer use it too); this is its Python face.

    Parameters
    ----------
    x, y : float or (K,) array
        The robot's axle midpoint [m], or the last trailer's with ``from_last``.
    headings : (n+1,) or (K, n+1) array
        theta_0..theta_n [rad].
    geometry : ChainGeometry
    from_last : bool
        ``x, y`` are the last trailer's position (else the robot's).

    Returns
    -------
    (x, y)
        Each (n+1,) for one state, (K, n+1) for K states.
    """
    theta = np.asarray(headings, dtype=float)
    nb = geometry.n + 1
    if theta.shape[-1:] != (nb,) or theta.ndim > 2:
        raise ValueError(f"headings has shape {theta.shape}: need ({nb},) or (K, {nb})")
    rows = np.ascontiguousarray(theta.reshape(-1, nb))
    k = rows.shape[0]
    xa = np.ascontiguousarray(np.broadcast_to(np.asarray(x, dtype=float), (k,)))
    ya = np.ascontiguousarray(np.broadcast_to(np.asarray(y, dtype=float), (k,)))
    out_x, out_y = np.empty((k, nb)), np.empty((k, nb))
    front = np.ascontiguousarray(geometry.front, dtype=float)
    rear = np.ascontiguousarray(geometry.rear, dtype=float)
    chain = native.PtChain(geometry.n, native.dptr(front), native.dptr(rear))
    work = np.empty(2 * nb)
    native.load().pt_body_positions(ctypes.byref(chain), k, native.dptr(rows), native.dptr(xa),
                                    native.dptr(ya), int(bool(from_last)), native.dptr(out_x),
                                    native.dptr(out_y), native.dptr(work))
    if theta.ndim == 1:
        return out_x[0], out_y[0]
    return out_x, out_y


def velocities_from_last(phi, v_n: float, w_n: float, front, rear) -> tuple[float, list]:
    """Scalar form of :func:`inverse_velocities` for per-step loops: the robot's speed v0
    [m/s] and the yaw rates [w_0, ..., w_n] [rad/s] that make trailer n move with (v_n, w_n).

    ``phi`` (n,) joint angles [rad]; ``front``/``rear`` the links F_i, R_{i-1} [m] as sequences
    of floats.
    """
    n = len(front)
    w = [0.0] * (n + 1)
    v, w[n] = float(v_n), float(w_n)
    for i in range(n - 1, -1, -1):
        c, s = cos(phi[i]), sin(phi[i])
        v, w[i] = c * v + front[i] * s * w[i + 1], (s * v - front[i] * c * w[i + 1]) / rear[i]
    return v, w


def robot_velocity_from_last(phi, v_n: float, w_n: float, front, rear) -> tuple[float, float]:
    """Robot (v0 [m/s], w0 [rad/s]) making trailer n move with (v_n, w_n) (Step 3, Eq. 5);
    arguments as :func:`velocities_from_last`."""
    v, w = velocities_from_last(phi, v_n, w_n, front, rear)
    return v, w[0]


def steady_joint_angle(radius: float, link: float = LINK) -> float:
    """Steady joint angle [rad] on a circle of ``radius`` [m] when F = R = ``link`` [m].

    It is 2 atan(D/rho), with D = ``link`` and rho = ``radius``.
    """
    return 2.0 * float(np.arctan(link / radius))


def eq5_matrix(theta, link: float) -> np.ndarray:
    """The paper's Eq. (5) matrix mapping (v_n, dtheta_n/dt) to (v_0, w_0) for D = F = R = ``link``.

    ``psi_n = sum_k (-1)^(k-1) (theta_{k-1} - theta_k)``. Written from the paper, independently of
    :func:`inverse_velocities`, so tests can compare the two.
    """
    theta = np.asarray(theta, dtype=float)
    n = theta.size - 1
    k = np.arange(1, n + 1)
    psi = float(np.sum((-1.0) ** (k - 1) * (theta[:-1] - theta[1:])))
    sign = (-1.0) ** (n - 1)
    d = float(link)
    return np.array(
        [[np.cos(psi), sign * d * np.sin(psi)], [np.sin(psi) / d, -sign * np.cos(psi)]]
    )
