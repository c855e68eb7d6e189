"""Tests of the fixed-step RK4 helper (tests/reference/ode.py, the form of core/csrc/ode.h)."""

import math

import pytest
from reference.ode import rk4_step


@pytest.mark.parametrize("h", [0.1, -0.05, 0.5])
def test_one_step_on_exponential_growth_is_the_fourth_order_taylor_polynomial(h):
    """For dz/dt = lam z one RK4 step multiplies z by 1 + x + x²/2 + x³/6 + x⁴/24, x = lam h."""
    lam = -1.3
    x = lam * h
    (z,) = rk4_step(lambda _t, z: [lam * z[0]], 0.0, [2.0], h)
    assert z == pytest.approx(2.0 * (1 + x + x**2 / 2 + x**3 / 6 + x**4 / 24), rel=1e-14)


def test_time_dependent_cubic_right_hand_side_is_integrated_exactly():
    f = lambda t, _z: [4.0 * t**3 - 3.0 * t**2, math.cos(t)]  # noqa: E731
    t0, h = 0.7, 0.3
    z = rk4_step(f, t0, [1.0, 0.0], h)
    assert z[0] == pytest.approx(1.0 + (t0 + h) ** 4 - (t0 + h) ** 3 - t0**4 + t0**3, rel=1e-14)
    assert z[1] == pytest.approx(math.sin(t0 + h) - math.sin(t0), abs=h**5 / 2880)  # Simpson


def test_global_error_is_fourth_order():
    """Halving the step divides the error of a rotation after 1 s by about 16."""
    def rotate(_t, z):
        return [-z[1], z[0]]

    errors = []
    for m in (10, 20):
        z = [1.0, 0.0]
        for k in range(m):
            z = rk4_step(rotate, k / m, z, 1.0 / m)
        errors.append(math.hypot(z[0] - math.cos(1.0), z[1] - math.sin(1.0)))
    assert errors[0] / errors[1] == pytest.approx(16.0, rel=0.1)
