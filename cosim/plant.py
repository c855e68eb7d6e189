"""The plant's set-up for a run: the TrailerTrain FMU's parameters (:class:`PlantConfig`) and the
train's initial configuration (:class:`InitialState`), both as FMU start values."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated, Literal

import numpy as np
from pydantic import Field

from pushtrain.core.kinematics import ChainGeometry, body_positions
from pushtrain.core.reference import Reference
from pushtrain.errors import CosimInputError
from pushtrain.fmu.variables import scalars_for, variables_for
from pushtrain.settings import angle_setting, setting
from pushtrain.table1 import LINK
from pushtrain.validation import NonNegFloat, PositiveFloat, no_bool

__all__ = ["PlantConfig", "InitialState"]

_START = {v.name.split("[")[0]: v.start for v in (*scalars_for(2), *variables_for(1))
          if v.name != "rear[0]"}
"""The FMU's start value of each parameter (its variable table; a per-trailer array's is the
first trailer's, the same for every trailer)."""


@dataclass
class PlantConfig:
    """Parameters of the TrailerTrain FMU (names as in the FMU; arrays per trailer i = 1..n).

    ``front`` holds F_1..F_n, ``rear`` R_0..R_{n-1} [m]; ``mass``, ``payload`` [kg],
    ``inertia`` [kg m^2], ``mu`` [-] per trailer (one value or n). ``None`` keeps the FMU's
    default. The defaults are the FMU's own start values (its variable table, which reads
    Table 1), and the fields a scenario sets say where: ``[train]`` (``mass``, ``inertia``,
    ``payload``, ``mu``, ``phi_max_deg``), ``[robot]`` (``tau``, ``acc_max``,
    ``alpha_max_deg``: the robot's velocity loop) and ``[fmu]`` (``slip_mode``,
    ``max_substep``); the scenario's sections are generated from these declarations
    (:mod:`pushtrain.settings`).
    """

    n_trailers: int
    front: Sequence[float] | float | None = None
    rear: Sequence[float] | float | None = None
    mass: Sequence[float] | float | None = setting(
        _START["mass"], PositiveFloat | list[PositiveFloat], part="train")
    inertia: Sequence[float] | float | None = setting(
        _START["inertia"], PositiveFloat | list[PositiveFloat], part="train")
    payload: Sequence[float] | float | None = setting(
        _START["payload"], NonNegFloat | list[NonNegFloat], part="train")
    mu: Sequence[float] | float | None = setting(
        _START["mu"], NonNegFloat | list[NonNegFloat], part="train")
    g: float | None = None
    robot_tau: float | None = setting(_START["robot_tau"], PositiveFloat, part="robot", key="tau")
    robot_acc_max: float | None = setting(_START["robot_acc_max"], PositiveFloat, part="robot",
                                          key="acc_max")
    robot_alpha_max: float | None = angle_setting(
        math.degrees(_START["robot_alpha_max"]), PositiveFloat, part="robot", key="alpha_max_deg")
    phi_max: float | None = angle_setting(
        math.degrees(_START["phi_max"]), Annotated[float, Field(gt=0, lt=180)], part="train")
    slip_mode: int | None = setting(
        _START["slip_mode"], Annotated[Literal[0, 1], no_bool("0 or 1")], part="fmu")
    max_substep: float | None = setting(_START["max_substep"], PositiveFloat, part="fmu")
    slip_substep: float | None = None

    def _array(self, name: str, first: int):
        value = getattr(self, name)
        if value is None:
            return None
        arr = np.broadcast_to(np.asarray(value, dtype=float), (self.n_trailers,))
        return {f"{name}[{first + k}]": float(arr[k]) for k in range(self.n_trailers)}

    def geometry(self) -> ChainGeometry:
        """The plant's true hitch geometry (default: Table 1's link D)."""
        n = self.n_trailers
        front = np.broadcast_to(np.asarray(LINK if self.front is None else self.front, float), (n,))
        rear = np.broadcast_to(np.asarray(LINK if self.rear is None else self.rear, float), (n,))
        return ChainGeometry(front.copy(), rear.copy())

    def start_values(self) -> dict:
        """FMU start values for the parameters that are set."""
        out = {}
        for name, first in (("front", 1), ("rear", 0), ("mass", 1), ("inertia", 1),
                            ("payload", 1), ("mu", 1)):
            values = self._array(name, first)
            if values:
                out.update(values)
        for name in ("g", "robot_tau", "robot_acc_max", "robot_alpha_max", "phi_max",
                     "slip_mode", "max_substep", "slip_substep"):
            value = getattr(self, name)
            if value is not None:
                out[name] = value
        return out


@dataclass
class InitialState:
    """Initial configuration: robot pose, all headings and robot velocities.

    Build it with :meth:`behind_reference` to place the train on the reference's start.
    """

    x0: float
    y0: float
    theta: np.ndarray  # (n+1,) [rad]
    v0: float = 0.0
    w0: float = 0.0

    @classmethod
    def behind_reference(
        cls,
        reference: Reference,
        geometry: ChainGeometry,
        lateral_offset: float = 0.0,
        heading_offset: float = 0.0,
        joint_angles: Sequence[float] | None = None,
    ) -> "InitialState":
        """A train whose last trailer starts at the reference's start pose.

        ``lateral_offset`` [m] moves the last trailer along the reference heading's left normal,
        ``heading_offset`` [rad] turns it; ``joint_angles`` (n,) [rad] bend the chain (default
        straight).
        """
        x, y, th = (float(a) for a in reference.start)
        th_n = th + heading_offset
        x += -math.sin(th) * lateral_offset
        y += math.cos(th) * lateral_offset
        n = geometry.n
        phi = np.zeros(n) if joint_angles is None else np.asarray(joint_angles, dtype=float)
        if phi.shape != (n,):
            raise CosimInputError(f"joint_angles has shape {phi.shape}; expected ({n},)")
        # theta_{i-1} = theta_i + phi_i, from the last trailer forward
        theta = th_n + np.concatenate((np.cumsum(phi[::-1])[::-1], [0.0]))
        xs, ys = body_positions(x, y, theta, geometry, from_last=True)
        return cls(float(xs[0]), float(ys[0]), theta)

    def start_values(self) -> dict:
        out = {"x0_start": self.x0, "y0_start": self.y0, "v_start": self.v0, "w_start": self.w0}
        out.update({f"theta_start[{i}]": float(a) for i, a in enumerate(self.theta)})
        return out
