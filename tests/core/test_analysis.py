"""Tests of the closed-form analysis (pushtrain.core.analysis)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from reference.controller import BackwardController

from pushtrain.core.analysis import (
    characteristic_polynomial,
    closed_loop_poles,
    effective_bias,
    eq12_matrix,
    is_hurwitz,
    routh_array,
    routh_hurwitz,
    steady_lateral_error,
    steady_lateral_error_estimated_pose,
)
from pushtrain.core.controller import ControllerConfig
from pushtrain.core.kinematics import (
    ChainGeometry,
    body_positions,
    forward_velocities,
)
from pushtrain.core.reference import ReferenceSample
from pushtrain.core.segment import PUSH
from pushtrain.core.sensors import Measurement
from pushtrain.errors import AnalysisError

gains = st.floats(0.1, 20.0)


def test_effective_bias_alternates_from_the_last_joint():
    assert effective_bias([0.0, 0.0, 0.1]) == pytest.approx(0.1)
    assert effective_bias([0.0, 0.1, 0.0]) == pytest.approx(-0.1)
    assert effective_bias([0.1, 0.0, 0.0]) == pytest.approx(0.1)
    assert effective_bias([0.1, 0.1]) == pytest.approx(0.0)
    eps = np.array([0.01, 0.02, -0.03, 0.04, 0.05])
    assert effective_bias(eps) == pytest.approx(0.01 - 0.02 - 0.03 - 0.04 + 0.05)
    with pytest.raises(AnalysisError):
        effective_bias([])


def test_steady_lateral_error_forms():
    eps = np.radians(5.0)
    exact = steady_lateral_error(eps, 0.52, 4.0)
    paper = steady_lateral_error(eps, 0.52, 4.0, form="paper")
    assert exact == pytest.approx(-np.sin(eps) / (0.52 * 4.0))
    assert paper == pytest.approx(-np.tan(eps) / (0.52 * 4.0))
    assert abs(paper - exact) / abs(exact) < eps**2  # small-angle agreement
    assert steady_lateral_error(-eps, 0.52, 4.0) == pytest.approx(-exact)
    with pytest.raises(AnalysisError, match="form"):
        steady_lateral_error(eps, 0.52, 4.0, form="tan")
    with pytest.raises(AnalysisError, match="link"):
        steady_lateral_error(eps, 0.0, 4.0)


def test_estimated_pose_error_reduces_to_its_parts():
    # no bias -> no error; a bias on the last joint of one trailer: by hand
    assert steady_lateral_error_estimated_pose([0.0, 0.0], 0.52, 1, 4, 4, 0.1) == 0.0
    e, d, ky, kth, kx, u = 0.1, 0.5, 3.0, 2.0, 1.5, 0.08
    y_est = -(np.sin(e) / d + kth * np.sin(e)) / ky  # theta_e(est) = eps, w_ref = -u sin(eps)/D
    by_hand = np.cos(e) * y_est - d * np.sin(e)  # x_e(est) = 0 when E = eps_eff
    assert steady_lateral_error_estimated_pose([e], d, kx, ky, kth, u) == pytest.approx(by_hand)


@settings(max_examples=50, deadline=None)
@given(kx=gains, ky=gains, kth=gains, v=st.floats(-1.0, 1.0), eps=st.floats(-0.3, 0.3))
def test_eq12_eigenvalues_are_the_eq13_roots(kx, ky, kth, v, eps):
    a = eq12_matrix(kx, ky, kth, v, 0.52, eps)
    eig = np.sort_complex(np.linalg.eigvals(a))
    poly = np.poly(a)  # characteristic polynomial from the matrix
    np.testing.assert_allclose(
        poly, characteristic_polynomial(kx, ky, kth, v), rtol=1e-9, atol=1e-9
    )
    roots = closed_loop_poles(kx, ky, kth, v)
    # compare as multisets (robust to ordering of near-equal roots)
    for r in roots:
        assert np.min(np.abs(eig - r)) <= 1e-5 * max(1.0, abs(r))


def _error(trailer, ref_pose):
    """Eq. 2 in the direction-of-travel frame (heading theta_n + pi), written out independently."""
    x, y, th = trailer
    xd, yd, thd = ref_pose
    tt = th + np.pi
    rot = np.array([[np.cos(tt), np.sin(tt)], [-np.sin(tt), np.cos(tt)]])
    xe, ye = rot @ np.array([xd - x, yd - y])
    return np.array([xe, ye, np.angle(np.exp(1j * (thd - th)))])


def _unicycle(pose, v, w, tau):
    """Exact unicycle motion over tau [s] with constant (v, w), pose = (x, y, theta)."""
    x, y, th = pose
    half = 0.5 * w * tau
    chord = v * tau * np.sinc(half / np.pi)  # sin(half) / half, no cancellation for small w
    return np.array([x + chord * np.cos(th + half), y + chord * np.sin(th + half), th + w * tau])


def closed_loop_error_rate(ctrl, geom, phi, e, u_d, thd=0.3, tau=1e-6):
    """d(x_e, y_e, theta_e)/dt of the kinematic plant under the controller, by time differences."""
    ref_pose = np.array([0.4, -0.7, thd])
    tt = thd - e[2] + np.pi
    rot = np.array([[np.cos(tt), -np.sin(tt)], [np.sin(tt), np.cos(tt)]])
    xn, yn = ref_pose[:2] - rot @ e[:2]
    thn = thd - e[2]
    theta = thn + np.concatenate(
        (np.cumsum(phi[::-1])[::-1], [0.0])
    )  # theta_{i-1} = theta_i + phi_i
    x, y = body_positions(xn, yn, theta, geom, from_last=True)
    meas = Measurement(x[0], y[0], theta[0], phi)
    ref = ReferenceSample(*ref_pose, -u_d, 0.0, PUSH)
    v0, w0, _ = ctrl.command(0.0, meas, ref)
    v, w = forward_velocities(phi, v0, w0, geom)  # the plant: true joint angles
    trailer = np.array([xn, yn, thn])
    rates = []
    for s in (-tau, tau):
        moved = _unicycle(trailer, v[-1], w[-1], s)
        ref_moved = _unicycle(ref_pose, -u_d, 0.0, s)
        rates.append(_error(moved, ref_moved))
    return (rates[1] - rates[0]) / (2 * tau)


@pytest.mark.parametrize("u_d", [0.05, 0.1, 0.3])
@pytest.mark.parametrize("gain_set", [(1.0, 4.0, 4.0), (2.0, 10.0, 3.0), (0.5, 1.0, 6.0)])
def test_eq13_roots_equal_the_numerical_linearization(u_d, gain_set):
    kx, ky, kth = gain_set
    geom = ChainGeometry.uniform(3, 0.52)
    ctrl = BackwardController(
        ControllerConfig(geom, k_x=kx, k_y=ky, k_theta=kth, v_max=10.0, w_max=10.0)
    )
    phi = np.array([0.1, -0.25, 0.15])  # any configuration: the inverse map is exact
    f0 = closed_loop_error_rate(ctrl, geom, phi, np.zeros(3), u_d)
    np.testing.assert_allclose(f0, 0.0, atol=1e-8)  # zero error is an equilibrium
    delta = 1e-4
    jac = np.empty((3, 3))
    for j in range(3):
        step = np.zeros(3)
        step[j] = delta
        jac[:, j] = (
            closed_loop_error_rate(ctrl, geom, phi, step, u_d)
            - closed_loop_error_rate(ctrl, geom, phi, -step, u_d)
        ) / (2 * delta)
    np.testing.assert_allclose(jac, eq12_matrix(kx, ky, kth, u_d, 0.52, 0.0), atol=1e-5)
    np.testing.assert_allclose(
        np.poly(jac), characteristic_polynomial(kx, ky, kth, u_d), rtol=1e-5, atol=1e-8
    )
    eig = np.linalg.eigvals(jac)
    for r in closed_loop_poles(kx, ky, kth, u_d):
        # the default gains give a double root, whose numerical split is ~sqrt(jacobian error)
        assert np.min(np.abs(eig - r)) < 2e-3 * max(1.0, abs(r))
    assert np.all(eig.real < 0)


@settings(max_examples=60, deadline=None)
@given(kx=gains, ky=gains, kth=gains, v=st.floats(0.01, 2.0))
def test_routh_hurwitz_verdict_flips_with_the_sign_of_v_d(kx, ky, kth, v):
    assert is_hurwitz(kx, ky, kth, v)
    assert not is_hurwitz(kx, ky, kth, -v)
    assert np.all(closed_loop_poles(kx, ky, kth, v).real < 0)
    assert np.any(closed_loop_poles(kx, ky, kth, -v).real > 0)


def test_routh_hurwitz_agrees_with_roots_for_random_polynomials():
    rng = np.random.default_rng(5)
    checked = 0
    for _ in range(2000):
        degree = rng.integers(1, 7)
        coeffs = rng.normal(size=degree + 1)
        roots = np.roots(coeffs)
        if np.min(np.abs(roots.real)) < 1e-6:
            continue  # marginal: leave it to the exact zero cases below
        result = routh_hurwitz(coeffs)
        assert result.stable == bool(np.all(roots.real < 0))
        if np.all(np.isfinite(result.first_column)) and np.all(result.first_column != 0):
            assert result.sign_changes == int(np.sum(roots.real > 0))
        checked += 1
    assert checked > 1500
    # stable by construction, and marginal cases
    assert routh_hurwitz(np.poly([-1.0, -2.0 + 1j, -2.0 - 1j, -0.5]).real).stable
    assert not routh_hurwitz([1.0, 0.0, 1.0]).stable  # roots +-i
    assert not routh_hurwitz([1.0, 1.0, 0.0]).stable  # root 0
    table = routh_array([1.0, 6.0, 11.0, 6.0])  # (s+1)(s+2)(s+3)
    np.testing.assert_allclose(table[:, 0], [1.0, 6.0, 10.0, 6.0])
    with pytest.raises(AnalysisError):
        routh_array([0.0, 1.0])
