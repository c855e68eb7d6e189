"""The robot's own RK4 in slip_mode 1 (fmu/src/slip.c, ``robot_rk4``) against the closed form.

While a wheel slides, the FMU moves the robot with an RK4 of its own (its motion does not depend
on the trailers). At constant commands equal to its start velocities the robot drives an exact
circle: x = (v/w) sin(w t), y = (v/w) (1 - cos(w t)), theta = w t. A wrong stage weight
(``{0, 0.5, 1.0, 1.0}`` for ``{0, 0.5, 0.5, 1.0}``) evaluates the third stage a whole substep
ahead: about v w T dt / 6 = 8e-6 m off after 2 s of 0.5 ms substeps; RK4 itself is exact to
round-off here.
"""

from __future__ import annotations

import math

import numpy as np

V, W, H, T = 0.1, 0.5, 0.005, 2.0


def test_the_robot_drives_the_exact_circle_while_the_wheels_slide(built_fmu_sim):
    sim = built_fmu_sim(3)
    # mu = 0: rolling would need lateral forces friction cannot give, so every substep is
    # the sliding one (the robot moved by robot_rk4)
    sim.initialize({"slip_mode": 1, "v_start": V, "w_start": W,
                    **{f"mu[{i}]": 0.0 for i in (1, 2, 3)}},
                   {"v_cmd": V, "w_cmd": W})
    errors, sliding = [], []
    for k in range(1, int(round(T / H)) + 1):
        sim.step(H)
        t = k * H
        x, y, theta, v, w = sim.get(["x[0]", "y[0]", "theta[0]", "v[0]", "w[0]"])
        assert (v, w) == (V, W)  # the commands equal the start velocities: no transient
        expected = (V / W * math.sin(W * t), V / W * (1.0 - math.cos(W * t)), W * t)
        errors.append(max(abs(x - expected[0]), abs(y - expected[1]), abs(theta - expected[2])))
        sliding.append(bool(np.any(sim.array("slipping"))))
    assert all(sliding[1:]), "the wheels must slide, or robot_rk4 is not what moved the robot"
    assert max(errors) < 1e-10, max(errors)
