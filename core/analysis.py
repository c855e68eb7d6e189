"""Closed-form analysis of the backward-motion controller (Section 3.1 of the paper; no simulation).

Sign conventions (those of :mod:`pushtrain.core.controller`): a joint bias is
``eps_k = phi_k(measured) - phi_k(true)`` [rad], joints k = 1..n; tracking errors are Kanayama's
``(x_e, y_e, theta_e)`` of the last trailer in its direction-of-travel frame (heading
``theta_n + pi`` when pushing), so ``y_e`` is the reference's lateral position *minus* the
trailer's, measured along the left normal of the direction of travel; the reference speed
``v_d`` of Eq. 12-13 is the speed in that frame (``v_d > 0`` when pushing with the controller).

Joint biases and the steady offset on a straight reference, uniform links D = F = R:

* The velocity map with measured angles composed with the true one gives, at the steady straight
  configuration, the last trailer's velocity ``T(-eps_eff) (v_ref, w_ref)`` with
  ``T(a) = [[cos a, -D sin a], [sin a / D, cos a]]`` and ``eps_eff = sum_k (-1)^(n-k) eps_k``
  (:func:`effective_bias`).
* If the last trailer's pose is measured directly (bias only in Step 3, the paper's setting of
  Eq. 6-9), w_act = 0 needs ``w_ref = -u_d sin(eps_eff) / D`` with ``theta_e = 0``, so Eq. 4 gives
  ``y_e = -sin(eps_eff) / (D K_y)`` exactly (:func:`steady_lateral_error`); the paper's Eq. 9,
  ``-tan(eps)/(D K_y)``, is its small-angle form.
* If the last trailer's pose is computed from the robot pose and the biased joint angles (what the
  controller does without a direct measurement), its heading estimate is off by the plain sum
  ``E = sum_k eps_k`` and its position estimate is shifted as well; the exact steady error is
  :func:`steady_lateral_error_estimated_pose`. For a bias on the last joint it is about 4 times
  larger than ``sin(eps)/(D K_y)`` with the default gains, and a bias on joint n-1 does *not*
  flip its sign.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from pushtrain.errors import AnalysisError

__all__ = ["RouthResult", "characteristic_polynomial", "closed_loop_poles", "effective_bias",
           "eq12_matrix", "is_hurwitz", "routh_array", "routh_hurwitz", "steady_lateral_error",
           "steady_lateral_error_estimated_pose"]


def _finite(name: str, value) -> float:
    value = float(value)
    if not np.isfinite(value):
        raise AnalysisError(f"{name} = {value!r}: must be finite")
    return value


def _positive(name: str, value) -> float:
    value = _finite(name, value)
    if value <= 0.0:
        raise AnalysisError(f"{name} = {value!r}: must be > 0")
    return value


def _biases(biases) -> np.ndarray:
    eps = np.asarray(biases, dtype=float).reshape(-1)
    if eps.size < 1:
        raise AnalysisError("biases: need one bias per joint (n >= 1), got none")
    bad = np.flatnonzero(~np.isfinite(eps))
    if bad.size:
        raise AnalysisError(f"biases[{bad[0]}] = {eps[bad[0]]!r} rad: must be finite")
    return eps


def effective_bias(biases) -> float:
    """Effective bias [rad] of joint biases eps_1..eps_n [rad] at the last trailer.

    ``eps_eff = sum_{k=1}^{n} (-1)^(n-k) eps_k``: biases add with alternating signs, the last
    joint's with +1.
    """
    eps = _biases(biases)
    n = eps.size
    signs = (-1.0) ** (n - np.arange(1, n + 1))
    return float(np.sum(signs * eps))


def steady_lateral_error(eps_eff: float, link: float, k_y: float, form: str = "exact") -> float:
    """Steady lateral error y_e [m] on a straight reference under an effective joint bias.

    Valid when the last trailer's pose is known (the bias acts only on the velocity map, Eq. 6-7).

    Parameters
    ----------
    eps_eff : float
        Effective bias [rad] (:func:`effective_bias`).
    link : float
        D = F = R [m], > 0.
    k_y : float
        Lateral gain K_y [1/m²], > 0.
    form : {"exact", "paper"}
        ``"exact"``: ``-sin(eps_eff)/(D K_y)``; ``"paper"``: Eq. 9, ``-tan(eps_eff)/(D K_y)``.
    """
    eps = _finite("eps_eff", eps_eff)
    d = _positive("link", link)
    k_y = _positive("k_y", k_y)
    if form == "exact":
        return -np.sin(eps) / (d * k_y)
    if form == "paper":
        return -np.tan(eps) / (d * k_y)
    raise AnalysisError(f"form = {form!r}: allowed are 'exact' and 'paper'")


def steady_lateral_error_estimated_pose(
    biases, link: float, k_x: float, k_y: float, k_theta: float, speed: float
) -> float:
    """True steady lateral error y_e [m] with the last trailer's pose estimated from biased joints.

    Straight reference, uniform links D = F = R = ``link`` [m], biases eps_1..eps_n [rad]
    (measured minus true), gains K_x [1/s], K_y [1/m²], K_theta [1/m], reference speed |v_d| =
    ``speed`` [m/s] > 0. At the steady state the true chain is straight and parallel to the
    reference, the estimated headings are ``theta_i - sum_{k<=i} eps_k`` and::

        E = sum_k eps_k,  e = eps_eff
        theta_e(est) = E
        x_e(est) = u_d (cos e - cos E) / K_x             (Eq. 3 with v_act = v_ref / cos e)
        y_e(est) = -(sin(e) / D + K_theta sin E) / K_y   (Eq. 4 with w_ref = -u_d sin(e) / D)
        y_e(true) = cos(E) y_e(est) - sin(E) x_e(est) + D sum_{i=1}^{n} (sin th_{i-1} + sin th_i)

    where ``th_i = -sum_{k<=i} eps_k`` are the estimated headings relative to the true one (the
    last term is the lateral shift of the estimated trailer position).
    """
    eps = _biases(biases)
    d = _positive("link", link)
    k_x, k_y = _positive("k_x", k_x), _positive("k_y", k_y)
    k_theta, u_d = _positive("k_theta", k_theta), _positive("speed", speed)
    e = effective_bias(eps)
    big_e = float(np.sum(eps))
    x_est = u_d * (np.cos(e) - np.cos(big_e)) / k_x
    y_est = -(np.sin(e) / d + k_theta * np.sin(big_e)) / k_y
    th = -np.concatenate(([0.0], np.cumsum(eps)))
    shift = d * float(np.sum(np.sin(th[:-1]) + np.sin(th[1:])))
    return float(np.cos(big_e) * y_est - np.sin(big_e) * x_est + shift)


def eq12_matrix(
    k_x: float, k_y: float, k_theta: float, v_d: float, link: float, eps: float = 0.0
) -> np.ndarray:
    """The linearized error dynamics matrix A of Eq. 12 (as printed in the paper), shape (3, 3).

    ``A = [[-K_x, v_d K_y D eps, K_theta D eps], [0, 0, v_d], [0, -v_d K_y, -v_d K_theta]]`` for the
    state (x_e, y_e, theta_e). Note: the printed entry ``A[0, 2] = K_theta D eps`` lacks the factor
    v_d that the derivation from Eq. 4 and 7 gives (``-D sin(eps) w_ref`` with
    ``w_ref = v_d K_theta theta_e``); it does not affect the eigenvalues, which are those of the
    lower-right block and ``-K_x`` whatever eps is (Eq. 13).
    """
    k_x, k_y, k_theta = (
        _finite(n, v) for n, v in (("k_x", k_x), ("k_y", k_y), ("k_theta", k_theta))
    )
    v_d, d, eps = _finite("v_d", v_d), _positive("link", link), _finite("eps", eps)
    return np.array(
        [
            [-k_x, v_d * k_y * d * eps, k_theta * d * eps],
            [0.0, 0.0, v_d],
            [0.0, -v_d * k_y, -v_d * k_theta],
        ]
    )


def characteristic_polynomial(k_x: float, k_y: float, k_theta: float, v_d: float) -> np.ndarray:
    """Coefficients [a1, a2, a3, a4] of Eq. 13, highest power first.

    ``s³ + (v_d K_theta + K_x) s² + (v_d² K_y + v_d K_x K_theta) s + v_d² K_x K_y``.
    """
    k_x, k_y, k_theta = (
        _finite(n, v) for n, v in (("k_x", k_x), ("k_y", k_y), ("k_theta", k_theta))
    )
    v = _finite("v_d", v_d)
    return np.array([1.0, v * k_theta + k_x, v * v * k_y + v * k_x * k_theta, v * v * k_x * k_y])


def closed_loop_poles(k_x: float, k_y: float, k_theta: float, v_d: float) -> np.ndarray:
    """Roots [1/s] of Eq. 13 (complex array of 3), sorted by real part then imaginary part."""
    roots = np.roots(characteristic_polynomial(k_x, k_y, k_theta, v_d))
    return np.sort_complex(roots.astype(complex))


def routh_array(coeffs) -> np.ndarray:
    """Routh array of a real polynomial (highest power first), shape (degree + 1, columns).

    A zero in the first column (which makes the next row undefined) ends the table there: the
    remaining rows are NaN. Such a polynomial is not Hurwitz (it has roots on or right of the
    imaginary axis).
    """
    a = np.asarray(coeffs, dtype=float).reshape(-1)
    if a.size < 2 or a[0] == 0.0 or not np.all(np.isfinite(a)):
        raise AnalysisError(
            f"coeffs = {a.tolist()!r}: need >= 2 finite coefficients with a non-zero leading one"
        )
    degree = a.size - 1
    cols = degree // 2 + 1
    table = np.full((degree + 1, cols), np.nan)
    table[0, :] = 0.0
    table[1, :] = 0.0
    table[0, : a[0::2].size] = a[0::2]
    table[1, : a[1::2].size] = a[1::2]
    for r in range(2, degree + 1):
        pivot = table[r - 1, 0]
        if pivot == 0.0 or not np.isfinite(pivot):
            break
        row = np.zeros(cols)
        for c in range(cols - 1):
            row[c] = (pivot * table[r - 2, c + 1] - table[r - 2, 0] * table[r - 1, c + 1]) / pivot
        table[r] = row
    return table


class RouthResult(NamedTuple):
    """Routh-Hurwitz verdict: ``stable`` (all roots in the open left half plane), the first column
    of the Routh array, and the number of sign changes in it (= roots in the right half plane when
    no zero occurs)."""

    stable: bool
    first_column: np.ndarray
    sign_changes: int


def routh_hurwitz(coeffs) -> RouthResult:
    """Routh-Hurwitz test of a real polynomial given highest power first."""
    first = routh_array(coeffs)[:, 0]
    complete = bool(np.all(np.isfinite(first)) and np.all(first != 0.0))
    signs = np.sign(first[np.isfinite(first) & (first != 0.0)])
    changes = int(np.sum(signs[1:] != signs[:-1]))
    return RouthResult(complete and changes == 0, first, changes)


def is_hurwitz(k_x: float, k_y: float, k_theta: float, v_d: float) -> bool:
    """Whether Eq. 13 is Hurwitz (linearized closed loop asymptotically stable) for these values."""
    return routh_hurwitz(characteristic_polynomial(k_x, k_y, k_theta, v_d)).stable
