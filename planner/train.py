"""The train as the planner sees it: its chain geometry, joint limit and body footprints.

Bodies are rectangles attached to their axle midpoints (the robot's centre for body 0): a
:class:`BodyFootprint` is ``length`` along the body heading, ``width`` across it, and ``offset``,
the signed distance [m] from the axle midpoint to the rectangle's centre along the heading
``theta`` (positive toward the robot, the chain convention of :mod:`pushtrain.core.kinematics`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from pushtrain.core.kinematics import ChainGeometry
from pushtrain.defaults import ROBOT_LENGTH, ROBOT_WIDTH
from pushtrain.errors import PlanningInputError
from pushtrain.table1 import LINK, TRAILER_LENGTH, TRAILER_WIDTH

__all__ = ["BodyFootprint", "Train"]


@dataclass(frozen=True)
class BodyFootprint:
    """Rectangle of one body in its own frame.

    Parameters
    ----------
    length : float
        Extent along the body heading [m], > 0.
    width : float
        Extent across the body heading [m], > 0.
    offset : float
        Rectangle centre minus axle midpoint along the heading theta (toward the robot) [m];
        must keep the axle midpoint inside the rectangle (|offset| <= length / 2).
    """

    length: float = TRAILER_LENGTH
    width: float = TRAILER_WIDTH
    offset: float = 0.0

    def __post_init__(self):
        for name in ("length", "width"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0.0):
                raise PlanningInputError(f"footprint {name} = {value!r} m: must be finite and > 0")
        if not (np.isfinite(self.offset) and abs(self.offset) <= 0.5 * self.length):
            raise PlanningInputError(
                f"footprint offset = {self.offset!r} m: the axle midpoint must lie inside the "
                f"rectangle, |offset| <= length/2 = {0.5 * self.length}"
            )

    def corners(self, x, y, theta) -> np.ndarray:
        """Corners [m] of the rectangle at axle-midpoint poses; shape (..., 4, 2), CCW order."""
        x, y, theta = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (x, y, theta)))
        c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]
        hl, hw = 0.5 * self.length, 0.5 * self.width
        along = self.offset + np.array([hl, -hl, -hl, hl])
        across = np.array([hw, hw, -hw, -hw])
        px = x[..., None] + along * c - across * s
        py = y[..., None] + along * s + across * c
        return np.stack([px, py], axis=-1)

    def corner_points(self, x: float, y: float, theta: float) -> tuple:
        """Corners of the rectangle at one pose as four (x, y) tuples [m], the order of
        :meth:`corners` (a fast scalar form for the planner's validity checks)."""
        c, s = math.cos(theta), math.sin(theta)
        hl, hw = 0.5 * self.length, 0.5 * self.width
        front, back = self.offset + hl, self.offset - hl
        return ((x + front * c - hw * s, y + front * s + hw * c),
                (x + back * c - hw * s, y + back * s + hw * c),
                (x + back * c + hw * s, y + back * s - hw * c),
                (x + front * c + hw * s, y + front * s - hw * c))

    def polygons(self, x, y, theta) -> np.ndarray:
        """Shapely polygons of the rectangle at the given poses (array of the broadcast shape)."""
        import shapely  # here: a run without a map never needs it

        return shapely.polygons(self.corners(x, y, theta))

    def to_dict(self) -> dict:
        """Plain data."""
        return {"length": self.length, "width": self.width, "offset": self.offset}


@dataclass(frozen=True)
class Train:
    """Geometry, footprints and joint limit of a robot with n trailers.

    Parameters
    ----------
    geometry : ChainGeometry
        Hitch links F_i, R_i [m].
    robot : BodyFootprint
        Body 0 (its reference point is the robot centre).
    trailers : tuple of BodyFootprint
        Bodies 1..n, one per trailer (own sizes allowed).
    phi_max : float
        Limit on every |phi_i| [rad] (the FMU's ``phi_max``), in (0, pi).
    """

    geometry: ChainGeometry
    robot: BodyFootprint = BodyFootprint(ROBOT_LENGTH, ROBOT_WIDTH, 0.0)
    trailers: tuple = ()
    phi_max: float = 0.5 * np.pi

    def __post_init__(self):
        trailers = tuple(self.trailers) or (BodyFootprint(),) * self.geometry.n
        if len(trailers) != self.geometry.n:
            raise PlanningInputError(
                f"{len(trailers)} trailer footprints for a chain of n = {self.geometry.n} trailers"
            )
        object.__setattr__(self, "trailers", trailers)
        if not (np.isfinite(self.phi_max) and 0.0 < self.phi_max < np.pi):
            raise PlanningInputError(f"phi_max = {self.phi_max!r} rad: allowed is (0, pi)")

    @classmethod
    def uniform(
        cls,
        n_trailers: int = 3,
        link: float = LINK,
        robot: BodyFootprint | None = None,
        trailer: BodyFootprint | None = None,
        phi_max: float = 0.5 * np.pi,
    ) -> "Train":
        """``n_trailers`` equal trailers (defaults: Table 1's 0.8 m x 0.6 m, D = 0.52 m)."""
        geometry = ChainGeometry.uniform(n_trailers, link)
        return cls(
            geometry,
            robot or BodyFootprint(ROBOT_LENGTH, ROBOT_WIDTH, 0.0),
            (trailer or BodyFootprint(),) * geometry.n,
            phi_max,
        )

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "Train":
        """From plain data: ``n_trailers`` (int), optional ``link`` (m, default 0.52) or
        ``front``/``rear`` lists, ``robot`` and ``trailer`` (one dict for all) or ``trailers``
        (a list of dicts) with ``length``/``width``/``offset``, and ``phi_max_deg``."""
        if "front" in data or "rear" in data:
            geometry = ChainGeometry(np.asarray(data["front"]), np.asarray(data["rear"]))
        else:
            geometry = ChainGeometry.uniform(int(data.get("n_trailers", 3)), data.get("link", LINK))
        robot = (BodyFootprint(**data["robot"]) if "robot" in data
                 else BodyFootprint(ROBOT_LENGTH, ROBOT_WIDTH))
        if "trailers" in data:
            trailers = tuple(BodyFootprint(**t) for t in data["trailers"])
        else:
            trailers = (BodyFootprint(**data.get("trailer", {})),) * geometry.n
        phi_max = np.radians(float(data.get("phi_max_deg", 90.0)))
        return cls(geometry, robot, trailers, phi_max)

    @property
    def n(self) -> int:
        """Number of trailers."""
        return self.geometry.n

    @property
    def bodies(self) -> tuple:
        """Footprints of bodies 0..n."""
        return (self.robot, *self.trailers)

    @property
    def last(self) -> BodyFootprint:
        """Footprint of the last trailer (the planned body)."""
        return self.trailers[-1]

    @property
    def hitch_length(self) -> float:
        """Distance [m] from the last trailer's axle to the robot's centre along a straight
        chain: the sum of every F_i and R_i."""
        return float(np.sum(self.geometry.front) + np.sum(self.geometry.rear))

    def max_link(self) -> float:
        """Largest hitch link max(F_i, R_i) [m]."""
        return float(max(self.geometry.front.max(), self.geometry.rear.max()))
