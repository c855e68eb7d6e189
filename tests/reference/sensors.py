"""The sensor model of ``pushtrain.core.sensors`` in numpy: the reference ``core/csrc/sensors.c``
is held equal to, bit for bit (``tests/core/test_sensors.py``).

Joint i: ``play_i <- clip(play_i, phi_i - b/2, phi_i + b/2)``, ``reading = play_i + bias_i +
N(0, joint_noise²)``, ``measured = q * round(reading / q)``; poses: true + N(0, std²). Noise is
drawn value block by value block with ``Generator.normal`` (joints, robot position, robot heading,
last trailer's position and heading), from a generator seeded as the product's.
"""

from __future__ import annotations

import numpy as np

from pushtrain.core.sensors import Measurement, SensorConfig


class ReferenceSensors:
    """The numpy sensor model of a :class:`SensorConfig` (same ``measure`` and ``set_bias``)."""

    def __init__(self, config: SensorConfig):
        self.config = config
        self.n = config.n_joints
        self.rng = np.random.default_rng(config.seed)
        self.bias = config.bias
        self.play = None

    def set_bias(self, joint: int, value: float) -> None:
        """Bias of joint ``joint`` (1..n) [rad] from now."""
        self.bias[joint - 1] = value

    def measure_joints(self, phi) -> np.ndarray:
        """Joint readings (n,) [rad] of the true angles ``phi`` (advances the play)."""
        phi = np.asarray(phi, dtype=float)
        c, half = self.config, 0.5 * self.config.joint_backlash
        if half == 0.0:
            reading = phi + self.bias
        else:
            if self.play is None:
                self.play = phi.copy()
            else:
                np.clip(self.play, phi - half, phi + half, out=self.play)
            reading = self.play + self.bias
        if c.joint_noise > 0.0:
            reading += self.rng.normal(0.0, c.joint_noise, self.n)
        if c.joint_quantization > 0.0:
            q = c.joint_quantization
            reading = q * np.round(reading / q)
        return reading

    def measure_pose(self, x: float, y: float, theta: float) -> tuple[float, float, float]:
        """One pose reading [m, m, rad]."""
        c = self.config
        if c.position_noise > 0.0:
            ex, ey = self.rng.normal(0.0, c.position_noise, 2)
            x, y = x + ex, y + ey
        if c.heading_noise > 0.0:
            theta = theta + self.rng.normal(0.0, c.heading_noise)
        return float(x), float(y), float(theta)

    def measure(self, x0, y0, theta0, phi, last_pose=None) -> Measurement:
        """The measurement of the true robot pose, joint angles and (if measured) last pose."""
        phi_meas = self.measure_joints(phi)
        robot = self.measure_pose(x0, y0, theta0)
        last = self.measure_pose(*last_pose) if self.config.measure_last_pose else None
        return Measurement(*robot, phi_meas, last)
