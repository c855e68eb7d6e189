"""Sensor models: robot localization and joint potentiometers (seeded noise, compiled model).

The controller sees the chain only through these measurements: the robot pose
``(x0, y0, theta0)`` from localization and the joint angles ``phi_i`` (i = 1..n) from the
potentiometers. Joint-angle errors are those of Section 3.1 of the paper (a constant bias per joint,
e.g. from wheel misalignment) plus backlash, noise and quantization.

Joint-angle pipeline, in this order, for joint i::

    play_i   <- clip(play_i, phi_i - b/2, phi_i + b/2)       backlash (play operator, band b)
    reading  =  play_i + bias_i + N(0, joint_noise²)
    measured =  q * round(reading / q)                        quantization (if q > 0)

``play_i`` starts at the first true angle seen (after :meth:`Sensors.reset`). Robot pose::

    x0_meas = x0 + N(0, position_noise²),  y0_meas likewise
    theta0_meas = theta0 + N(0, heading_noise²)

All noise comes from one ``numpy.random.Generator`` seeded by ``SensorConfig.seed``; a
disabled source (std 0) draws nothing. The model itself is written once, in C
(``core/csrc/sensors.c``, through :mod:`pushtrain.core.native`): the co-simulation master's
step loop and the controller FMU measure with the same code. This module validates the
configuration, draws the noise (:meth:`Sensors.draw_noise`, in the model's order) and holds the
model's memory (biases, play) where the C reads and writes it. The readable numpy version of the
model is the tests' reference (``tests/reference/sensors.py``), held equal bit for bit.
"""

from __future__ import annotations

import ctypes
import logging
from dataclasses import dataclass, field
from math import isfinite
from typing import Literal, NamedTuple

import numpy as np

from pushtrain.core import native
from pushtrain.errors import SensorError
from pushtrain.settings import angle_setting, setting
from pushtrain.validation import FiniteFloat, NonNegFloat

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
    joint_bias : float or sequence of n floats
        Constant bias added to each joint reading [rad] from the start (Section 3.1); a scalar
        applies to every joint. :meth:`Sensors.set_bias` changes it during a run.
    joint_noise : float
        Standard deviation of white Gaussian noise on each joint reading [rad], >= 0.
    joint_quantization : float
        Resolution of the joint readings [rad], >= 0 (0: none).
    joint_backlash : float
        Width of the dead band (play) between joint and potentiometer [rad], >= 0 (0: none).
    position_noise : float
        Standard deviation of the noise on x0 and y0 [m], >= 0.
    heading_noise : float
        Standard deviation of the noise on theta0 [rad], >= 0.
    localize : {"robot", "last_trailer"}
        What localization measures: the robot (the last trailer's pose is computed from the
        joint angles, the paper's prototype), or also the last trailer directly (the setting
        of Eq. 6-9; same position and heading noise as the robot's; :meth:`Sensors.measure`
        then needs the true ``last_pose``).
    seed : int or None
        Seed of the noise generator (``None``: fresh entropy, not reproducible).

    The fields but ``n_joints`` and ``seed`` are the scenario's ``[sensors]`` section (an angle
    as ``NAME_deg``, in degrees), generated from their declarations
    (:mod:`pushtrain.settings`).
    """

    n_joints: int
    joint_bias: float | tuple = angle_setting(0.0, FiniteFloat | list[FiniteFloat])
    joint_noise: float = angle_setting(0.0, NonNegFloat)
    joint_quantization: float = angle_setting(0.0, NonNegFloat)
    joint_backlash: float = angle_setting(0.0, NonNegFloat)
    position_noise: float = setting(0.0, NonNegFloat)
    heading_noise: float = angle_setting(0.0, NonNegFloat)
    localize: str = setting("robot", Literal["robot", "last_trailer"])
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
        if self.localize not in ("robot", "last_trailer"):
            raise SensorError(f"localize = {self.localize!r}: allowed are 'robot' and "
                              "'last_trailer'")
        for name in (
            "joint_noise",
            "joint_quantization",
            "joint_backlash",
            "position_noise",
            "heading_noise",
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

    @property
    def measure_last_pose(self) -> bool:
        """Localization measures the last trailer too (``localize = "last_trailer"``)."""
        return self.localize == "last_trailer"


# the noise blocks of one measurement (sensors.h PT_NOISE_*)
NOISE_JOINTS, NOISE_POSITION, NOISE_HEADING = 1, 2, 4


class Sensors:
    """Turns the true state into a :class:`Measurement` (see the module docstring for the model).

    Parameters
    ----------
    config : SensorConfig

    Attributes
    ----------
    n : int
        Joints.
    rng : numpy.random.Generator
        The noise generator (reseeded by :meth:`reset`).
    noise_scales : numpy.ndarray
        Standard deviation of each noise value of one measurement, in the model's order (joint
        angles, robot position and heading, then the last trailer's if measured; a source with
        std 0 has no entry) [rad or m].
    model : pushtrain.core.native.PtSensors
        The C model (``sensors.h``): it points at this object's bias and play arrays, so a
        step loop given it measures with this object's memory.
    """

    def __init__(self, config: SensorConfig):
        if not isinstance(config, SensorConfig):
            raise SensorError(f"config = {config!r}: must be a SensorConfig")
        self.config = config
        self.n = n = config.n_joints
        self._lib = native.load()
        joint, pos, heading = (config.joint_noise, config.position_noise,
                               config.heading_noise)
        pose = [pos, pos] * (pos > 0.0) + [heading] * (heading > 0.0)
        self.noise_scales = np.array([joint] * n * (joint > 0.0)
                                     + pose * (2 if config.measure_last_pose else 1), dtype=float)
        self._biases = config.bias
        self._play = np.zeros(n)
        self.model = native.PtSensors(
            n, native.dptr(self._biases), 0.5 * config.joint_backlash, config.joint_quantization,
            (NOISE_JOINTS if joint > 0.0 else 0) | (NOISE_POSITION if pos > 0.0 else 0)
            | (NOISE_HEADING if heading > 0.0 else 0), int(bool(config.measure_last_pose)),
            native.dptr(self._play), 0)
        if self._lib.pt_sensors_noise_count(ctypes.byref(self.model)) != self.noise_scales.size:
            raise SensorError("the compiled sensor model counts its noise values differently "
                              "from core/sensors.py: the binding does not match sensors.h")
        self._truth = np.zeros(n + 6)
        self._measurement = native.PtMeasurement()
        self.reset()

    def reset(self) -> None:
        """Restart: reseed the generator, restore the configured biases, forget the backlash."""
        self.rng = np.random.default_rng(self.config.seed)
        self._biases[:] = self.config.bias
        self.model.has_play = 0

    @property
    def bias(self) -> np.ndarray:
        """Current per-joint bias, shape (n,) [rad] (a copy)."""
        return self._biases.copy()

    @property
    def play(self) -> np.ndarray | None:
        """The potentiometers' positions, shape (n,) [rad] (a copy), or None before the first
        measurement or without backlash."""
        return self._play.copy() if self.model.has_play else None

    def set_bias(self, joint: int, value: float) -> None:
        """Set the bias of joint ``joint`` (1..n, as ``phi[joint]``) to ``value`` [rad] from now."""
        if isinstance(joint, bool) or int(joint) != joint or not 1 <= joint <= self.n:
            raise SensorError(f"joint = {joint!r}: must be an integer in 1..{self.n}")
        if not isfinite(value):
            raise SensorError(f"bias of joint {joint} = {value!r} rad: must be finite")
        self._biases[int(joint) - 1] = float(value)
        logger.debug("joint %d bias set to %g rad", joint, value)

    def draw_noise(self, measurements: int) -> np.ndarray | None:
        """The noise of the next ``measurements`` measurements, shape (measurements,
        ``noise_scales.size``), or None without noise: what ``Generator.normal`` would draw value
        by value in the model's order (``0.0 + std * z``), drawn in one block."""
        if not self.noise_scales.size:
            return None
        z = self.rng.standard_normal((measurements, self.noise_scales.size))
        np.multiply(z, self.noise_scales, out=z)
        z += 0.0  # Generator.normal's loc + scale * z (-0.0 becomes 0.0)
        return z

    def measurer(self, truth: np.ndarray, phi_meas: np.ndarray):
        """A function of no arguments that measures the true state in ``truth`` ((n + 6,):
        x0, y0, theta0, x_n, y_n, theta_n [m, rad], phi_1..phi_n [rad], the plant's order) with
        the next noise, writes the joint readings into ``phi_meas`` ((n,), contiguous) and returns
        the :class:`Measurement` (``phi`` a list of floats). For a loop: the arrays stay bound.
        """
        if truth.shape != (self.n + 6,) or phi_meas.shape != (self.n,):
            raise SensorError(f"truth has shape {truth.shape} and phi_meas {phi_meas.shape}: "
                              f"need ({self.n + 6},) and ({self.n},)")
        call, model, out = self._lib.pt_measure, ctypes.byref(self.model), self._measurement
        truth_ptr, phi_ptr, draw = native.dptr(truth), native.dptr(phi_meas), self.draw_noise
        noisy, last = self.noise_scales.size > 0, self.config.measure_last_pose
        new = tuple.__new__

        def measure() -> Measurement:
            noise = draw(1) if noisy else None
            call(model, truth_ptr, None if noise is None else native.dptr(noise), phi_ptr, out)
            return new(Measurement, (out.x0, out.y0, out.theta0, phi_meas.tolist(),
                                     (out.x_n, out.y_n, out.theta_n) if last else None))

        return measure

    def measure(self, x0: float, y0: float, theta0: float, phi, last_pose=None) -> Measurement:
        """Measurement of the true robot pose (x0, y0 [m], theta0 [rad]) and joint angles phi (n,).

        ``last_pose`` is the true (x_n, y_n, theta_n) [m, m, rad]; required when
        ``config.measure_last_pose`` is set, ignored otherwise. ``phi`` of the result is a new
        array.
        """
        phi = np.asarray(phi, dtype=float)
        if phi.shape != (self.n,):
            raise SensorError(f"phi has shape {phi.shape}: need ({self.n},)")
        truth = self._truth
        truth[:3] = x0, y0, theta0
        truth[6:] = phi
        if self.config.measure_last_pose:
            if last_pose is None or len(last_pose) != 3:
                raise SensorError(
                    f"last_pose = {last_pose!r}: localize = 'last_trailer', so the true"
                    " (x_n, y_n, theta_n) must be given"
                )
            truth[3:6] = last_pose
        reading = np.empty(self.n)
        m = self.measurer(truth, reading)()
        return Measurement(m.x0, m.y0, m.theta0, reading, m.last_pose)
