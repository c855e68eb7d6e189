"""Tests of the chain kinematics (pushtrain.core.kinematics)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pushtrain.core.kinematics import (
    ChainGeometry,
    body_positions,
    eq5_matrix,
    forward_velocities,
    heading_rates_from_robot,
    inverse_velocities,
    joint_angles,
    steady_joint_angle,
    wrap_angle,
)

angles = st.floats(-1.4, 1.4)
speeds = st.floats(-0.5, 0.5)
links = st.floats(0.1, 2.0)


@settings(max_examples=60, deadline=None)
@given(phi=angles, v=speeds, w=speeds, d=links)
def test_velocity_map_with_equal_links_is_its_own_inverse(phi, v, w, d):
    geom = ChainGeometry([d], [d])
    v1, w1 = forward_velocities([phi], v, w, geom)
    v2, w2 = forward_velocities([phi], v1[1], w1[1], geom)
    assert v2[1] == pytest.approx(v, abs=1e-12)
    assert w2[1] == pytest.approx(w, abs=1e-12)
    # the 2x2 map written out: M(phi) = [[c, D s], [s/D, -c]], M @ M = I
    c, s = np.cos(phi), np.sin(phi)
    m = np.array([[c, d * s], [s / d, -c]])
    np.testing.assert_allclose(m @ m, np.eye(2), atol=1e-12)
    np.testing.assert_allclose(m @ [v, w], [v1[1], w1[1]], atol=1e-12)


@settings(max_examples=80, deadline=None)
@given(
    n=st.integers(1, 5),
    data=st.data(),
    v=speeds,
    w=speeds,
    d=links,
)
def test_inverse_velocities_equals_eq5(n, data, v, w, d):
    theta = np.array(data.draw(st.lists(st.floats(-3.0, 3.0), min_size=n + 1, max_size=n + 1)))
    geom = ChainGeometry.uniform(n, d)
    vv, ww = inverse_velocities(joint_angles(theta), v, w, geom)
    expected = eq5_matrix(theta, d) @ np.array([v, w])
    np.testing.assert_allclose([vv[0], ww[0]], expected, atol=1e-10)


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 6), data=st.data(), v=speeds, w=speeds)
def test_forward_after_inverse_is_identity_for_general_links(n, data, v, w):
    front = data.draw(st.lists(links, min_size=n, max_size=n))
    rear = data.draw(st.lists(links, min_size=n, max_size=n))
    phi = np.array(data.draw(st.lists(angles, min_size=n, max_size=n)))
    geom = ChainGeometry(front, rear)
    vi, wi = inverse_velocities(phi, v, w, geom)
    vf, wf = forward_velocities(phi, vi[0], wi[0], geom)
    np.testing.assert_allclose(vf, vi, atol=1e-9)
    np.testing.assert_allclose(wf, wi, atol=1e-9)
    assert vf[-1] == pytest.approx(v, abs=1e-9) and wf[-1] == pytest.approx(w, abs=1e-9)


def test_towing_on_a_circle_gives_the_steady_joint_angle():
    """Robot on a circle of radius 2.5 m (forward, towing): every joint -> 2 atan(0.52 / 2.5)."""
    n, rho, v0 = 3, 2.5, 0.1
    geom = ChainGeometry.uniform(n, 0.52)
    w0 = v0 / rho
    theta = np.zeros(n + 1)
    h = 0.05

    def f(th):
        return heading_rates_from_robot(th, v0, w0, geom)

    for _ in range(int(400.0 / h)):  # RK4 on the headings only
        k1 = f(theta)
        k2 = f(theta + 0.5 * h * k1)
        k3 = f(theta + 0.5 * h * k2)
        k4 = f(theta + h * k3)
        theta = theta + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    phi = joint_angles(theta)
    expected = 2.0 * np.arctan(0.52 / 2.5)
    assert np.degrees(expected) == pytest.approx(23.50, abs=0.005)
    assert steady_joint_angle(2.5, 0.52) == pytest.approx(expected)
    np.testing.assert_allclose(phi, expected, atol=1e-6)
    # zero off-tracking for F = R: every body turns on the robot's circle
    x, y = body_positions(0.0, 0.0, theta, geom)
    centre = rho * np.array([-np.sin(theta[0]), np.cos(theta[0])])  # robot's circle, CCW turn
    radii = np.hypot(x - centre[0], y - centre[1])
    np.testing.assert_allclose(radii, rho, atol=1e-6)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 6), data=st.data(), x0=speeds, y0=speeds)
def test_body_positions_hitches_coincide(n, data, x0, y0):
    front = np.array(data.draw(st.lists(links, min_size=n, max_size=n)))
    rear = np.array(data.draw(st.lists(links, min_size=n, max_size=n)))
    theta = np.array(data.draw(st.lists(st.floats(-3.0, 3.0), min_size=n + 1, max_size=n + 1)))
    geom = ChainGeometry(front, rear)
    x, y = body_positions(x0, y0, theta, geom)
    assert (x[0], y[0]) == (x0, y0)
    for i in range(1, n + 1):
        rear_hitch = np.array([x[i - 1], y[i - 1]]) - rear[i - 1] * np.array(
            [np.cos(theta[i - 1]), np.sin(theta[i - 1])]
        )
        front_hitch = np.array([x[i], y[i]]) + front[i - 1] * np.array(
            [np.cos(theta[i]), np.sin(theta[i])]
        )
        np.testing.assert_allclose(rear_hitch, front_hitch, atol=1e-12)
    xl, yl = body_positions(x[-1], y[-1], theta, geom, from_last=True)
    np.testing.assert_allclose(xl, x, atol=1e-12)
    np.testing.assert_allclose(yl, y, atol=1e-12)


def test_wrap_angle_range():
    a = np.array([-np.pi, np.pi, 3 * np.pi, -3.5 * np.pi, 0.1])
    w = wrap_angle(a)
    assert np.all(w > -np.pi) and np.all(w <= np.pi)
    np.testing.assert_allclose(np.cos(w), np.cos(a), atol=1e-12)
    np.testing.assert_allclose(np.sin(w), np.sin(a), atol=1e-12)


@pytest.mark.parametrize(
    "front, rear", [([0.5], [0.5, 0.5]), ([0.0], [0.5]), ([0.5], [-1.0]), ([np.nan], [0.5])]
)
def test_bad_geometry_raises(front, rear):
    with pytest.raises(ValueError):
        ChainGeometry(front, rear)


def test_body_positions_of_many_states_are_each_states_own():
    """K states in one call (anchors per state or one for all) give each state's positions bit
    for bit, from the robot and from the last trailer; a heading array of another n is refused
    with the shape it had."""
    rng = np.random.default_rng(3)
    geom = ChainGeometry(rng.uniform(0.2, 1.0, 4), rng.uniform(0.2, 1.0, 4))
    theta = rng.uniform(-3.0, 3.0, (7, 5))
    xa, ya = rng.uniform(-5, 5, 7), rng.uniform(-5, 5, 7)
    for from_last in (False, True):
        x, y = body_positions(xa, ya, theta, geom, from_last=from_last)
        assert x.shape == y.shape == (7, 5)
        for k in range(7):
            xk, yk = body_positions(xa[k], ya[k], theta[k], geom, from_last=from_last)
            assert x[k].tobytes() == xk.tobytes() and y[k].tobytes() == yk.tobytes()
        anchor = 4 if from_last else 0
        assert np.array_equal(x[:, anchor], xa) and np.array_equal(y[:, anchor], ya)
        x0, _ = body_positions(1.5, -2.0, theta, geom, from_last=from_last)
        assert np.all(x0[:, anchor] == 1.5)
    with pytest.raises(ValueError, match=r"shape \(7, 4\)"):
        body_positions(0.0, 0.0, theta[:, :4], geom)
