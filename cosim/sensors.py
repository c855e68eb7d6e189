"""Sensor models: robot localization and joint potentiometers (pure numpy, seeded).

The controller sees the chain only through these measurements: the robot pose
``(x0, y0, theta0)`` from localization and the joint angles ``phi_i`` (i = 1..n) from the
potentiometers. Joint-angle errors are those of Section 3.1 of the paper (a constant bias per joint,
e.g. from wheel misalignment) plus backlash, noise and quantization.

Joint-angle pipeline, in this order, for joint i::

    play_i   <- clip(play_i, phi_i - b/2, phi_i + b/2)       backlash (play operator, band b)
    reading  =  play_i + bias_i + N(0, joint_noise_std²)
    measured =  q * round(reading / q)                        quantization (if q > 0)

``play_i`` starts at the first true angle seen (after :meth:`Sensors.reset`). Robot pose::

    x0_meas = x0 + N(0, pos_noise_std²),  y0_meas likewise
    theta0_meas = theta0 + N(0, heading_noise_std²)

All noise comes from one ``numpy.random.Generator`` seeded by ``SensorConfig.seed``; a
disabled source (std 0) draws nothing.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from math import isfinite
from typing import NamedTuple

import numpy as np

from pushtrain.errors import SensorError

__all__ = ["Measurement", "SensorConfig", "Sensors"]

logger = logging.getLogger(__name__)


class Measurement(NamedTuple):
    """What the controller sees.

    ``x0, y0, theta0``: robot pose [m, m, rad]; ``phi``: joint angles (n,) [rad], an array from
    :meth:`Sensors.measure`, a list of floats from the co-simulation master (the controller
    loops over it with plain floats);
    ``last_pose``: optional direct measurement ``(x_n, y_n, theta_n)`` of the last trailer
    [m, m, rad] (e.g. localization on the last trailer). When it is ``None`` the controller
    computes the last trailer's pose from the robot pose and the joint angles, so joint biases
    then also bias the pose estimate (see :mod:`pushtrain.core.analysis`).
    """

    x0: float
    y0: float
    theta0: float
    phi: np.ndarray | list[float]
    last_pose: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class SensorConfig:
    """Sensor errors.

    Parameters
    ----------
    n_joints : int
        Number of joints n (= trailers), >= 1.
    joint_bias : float or array of shape (n,)
        Constant bias added to each joint reading [rad] from the start (Section 3.1); a scalar
        applies to every joint. :meth:`Sensors.set_bias` changes it during a run.
    joint_noise_std : float
        Standard deviation of white Gaussian noise on each joint reading [rad], >= 0.
    joint_quantization : float
        Resolution of the joint readings [rad], >= 0 (0: none).
    joint_backlash : float
        Width of the dead band (play) between joint and potentiometer [rad], >= 0 (0: none).
    pos_noise_std : float
        Standard deviation of the noise on x0 and y0 [m], >= 0.
    heading_noise_std : float
        Standard deviation of the noise on theta0 [rad], >= 0.
    measure_last_pose : bool
        Also measure the last trailer's pose directly (same position and heading noise as the
        robot's); :meth:`Sensors.measure` then needs the true ``last_pose``.
    seed : int or None
        Seed of the noise generator (``None``: fresh entropy, not reproducible).
    """

    n_joints: int
    joint_bias: float | np.ndarray = 0.0
    joint_noise_std: float = 0.0
    joint_quantization: float = 0.0
    joint_backlash: float = 0.0
    pos_noise_std: float = 0.0
    heading_noise_std: float = 0.0
    measure_last_pose: bool = False
    seed: int | None = 0
    _bias: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        if (
            isinstance(self.n_joints, bool)
            or int(self.n_joints) != self.n_joints
            or self.n_joints < 1
        ):
            raise SensorError(f"n_joints = {self.n_joints!r}: must be an integer >= 1")
        object.__setattr__(self, "n_joints", int(self.n_joints))
        bias = np.asarray(self.joint_bias, dtype=float)
        if bias.ndim == 0:
            bias = np.full(self.n_joints, float(bias))
        if bias.shape != (self.n_joints,):
            raise SensorError(
                f"joint_bias has shape {bias.shape}: need a scalar or ({self.n_joints},)"
            )
        bad = np.flatnonzero(~np.isfinite(bias))
        if bad.size:
            raise SensorError(f"joint_bias[{bad[0]}] = {bias[bad[0]]!r} rad: must be finite")
        object.__setattr__(self, "_bias", bias)
        for name in (
            "joint_noise_std",
            "joint_quantization",
            "joint_backlash",
            "pos_noise_std",
            "heading_noise_std",
        ):
            value = getattr(self, name)
            if not (isfinite(value) and value >= 0.0):
                raise SensorError(f"{name} = {value!r}: must be finite and >= 0")
        if self.seed is not None and (
            isinstance(self.seed, bool) or int(self.seed) != self.seed or self.seed < 0
        ):
            raise SensorError(f"seed = {self.seed!r}: must be None or an integer >= 0")

    @property
    def bias(self) -> np.ndarray:
        """Initial per-joint bias, shape (n,) [rad] (a copy)."""
        return self._bias.copy()


class Sensors:
    """Turns the true state into a :class:`Measurement` (see the module docstring for the model).

    Parameters
    ----------
    config : SensorConfig
    """

    def __init__(self, config: SensorConfig):
        if not isinstance(config, SensorConfig):
            raise SensorError(f"config = {config!r}: must be a SensorConfig")
        self.config = config
        self.n = config.n_joints
        self._shape = (self.n,)
        self._half = 0.5 * config.joint_backlash
        self._joint_noise, self._q = config.joint_noise_std, config.joint_quantization
        self._pos_noise, self._heading_noise = config.pos_noise_std, config.heading_noise_std
        self.ideal = not (self._half or self._joint_noise or self._q or self._pos_noise
                          or self._heading_noise or config.measure_last_pose)
        """No noise, play, quantization or last-pose measurement: a reading is the true value
        (plus the joint biases), see :meth:`biased`."""
        self.reset()

    def reset(self) -> None:
        """Restart: reseed the generator, restore the configured biases, forget the backlash."""
        self._rng = np.random.default_rng(self.config.seed)
        self._bias = self.config.bias
        self._play = None

    @property
    def bias(self) -> np.ndarray:
        """Current per-joint bias, shape (n,) [rad] (a copy)."""
        return self._bias.copy()

    def set_bias(self, joint: int, value: float) -> None:
        """Set the bias of joint ``joint`` (1..n, as ``phi[joint]``) to ``value`` [rad] from now."""
        if isinstance(joint, bool) or int(joint) != joint or not 1 <= joint <= self.n:
            raise SensorError(f"joint = {joint!r}: must be an integer in 1..{self.n}")
        if not isfinite(value):
            raise SensorError(f"bias of joint {joint} = {value!r} rad: must be finite")
        self._bias[int(joint) - 1] = float(value)
        logger.debug("joint %d bias set to %g rad", joint, value)

    def biased(self, phi: np.ndarray) -> np.ndarray:
        """``phi`` (n,) [rad] plus the current joint biases (a new array): the joint readings of
        :attr:`ideal` sensors, equal to :meth:`measure_joints` for them (no checks: per step)."""
        return phi + self._bias

    def measure_joints(self, phi) -> np.ndarray:
        """Measured joint angles, shape (n,) [rad] (a new array), from the true ones (advances
        the backlash)."""
        phi = np.asarray(phi, dtype=float)
        if phi.shape != self._shape:
            raise SensorError(f"phi has shape {phi.shape}: need ({self.n},)")
        half = self._half
        if half == 0.0:  # no play: the potentiometer follows the joint
            reading = phi + self._bias
        else:
            if self._play is None:
                self._play = phi.copy()
            else:
                np.clip(self._play, phi - half, phi + half, out=self._play)
            reading = self._play + self._bias
        if self._joint_noise > 0.0:
            reading += self._rng.normal(0.0, self._joint_noise, self.n)
        if self._q > 0.0:
            reading = self._q * np.round(reading / self._q)
        return reading

    def measure_pose(self, x: float, y: float, theta: float) -> tuple[float, float, float]:
        """One pose reading [m, m, rad] (noisy if the config says so) of a true pose."""
        if self._pos_noise > 0.0:
            ex, ey = self._rng.normal(0.0, self._pos_noise, 2)
            x, y = x + ex, y + ey
        if self._heading_noise > 0.0:
            theta = theta + self._rng.normal(0.0, self._heading_noise)
        return float(x), float(y), float(theta)

    def measure(self, x0: float, y0: float, theta0: float, phi, last_pose=None) -> Measurement:
        """Measurement of the true robot pose (x0, y0 [m], theta0 [rad]) and joint angles phi (n,).

        ``last_pose`` is the true (x_n, y_n, theta_n) [m, m, rad]; required when
        ``config.measure_last_pose`` is set, ignored otherwise.
        """
        phi_meas = self.measure_joints(phi)
        robot = self.measure_pose(x0, y0, theta0)
        last = None
        if self.config.measure_last_pose:
            if last_pose is None or len(last_pose) != 3:
                raise SensorError(
                    f"last_pose = {last_pose!r}: measure_last_pose is set, so the true"
                    " (x_n, y_n, theta_n) must be given"
                )
            last = self.measure_pose(*last_pose)
        return Measurement(*robot, phi_meas, last)
