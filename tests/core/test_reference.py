"""Tests of the last trailer's reference (pushtrain.core.reference)."""

import numpy as np
import pytest

from pushtrain.core.reference import Reference
from pushtrain.core.sampled_reference import SampledReference
from pushtrain.core.segment import PULL, PUSH, REST, Segment


def mixed_reference(cusp_dwell=1.5):
    return Reference.from_segments(
        (0.3, -0.2, 0.4),
        [
            Segment("line", 1.0),
            Segment("arc", 1.2, 0.5),
            Segment("arc", 0.8, -0.3, direction=PULL, speed=0.05),
            Segment("line", 0.7, direction=PULL),
            Segment("arc", 1.0, 0.4),
        ],
        speed=0.1,
        cusp_dwell=cusp_dwell,
    )


def phase_boundaries(ref):
    return ref.phases[:, 0]


def test_eq1_holds_within_segments():
    """Central differences of x, y, theta equal (v cos theta, v sin theta, w) (Eq. 1, +x)."""
    ref = mixed_reference()
    t = np.linspace(ref.t0, ref.t_end, 4001)[1:-1]
    h = 1e-4
    bounds = np.append(phase_boundaries(ref), ref.t_end)
    inside = np.all(np.abs(t[:, None] - bounds[None, :]) > 2 * h, axis=1)
    t = t[inside]
    _x, _y, th, v, w = ref.sample(t)
    xp, yp, thp, _, _ = ref.sample(t + h)
    xm, ym, thm, _, _ = ref.sample(t - h)
    np.testing.assert_allclose((xp - xm) / (2 * h), v * np.cos(th), atol=1e-7)
    np.testing.assert_allclose((yp - ym) / (2 * h), v * np.sin(th), atol=1e-7)
    np.testing.assert_allclose((thp - thm) / (2 * h), w, atol=1e-7)
    d = ref.direction_at(t)
    assert set(np.unique(d)) <= {PUSH, PULL, REST}
    assert np.all(v[d == PUSH] < 0) and np.all(v[d == PULL] > 0)


def test_reference_is_continuous_and_reaches_the_goal():
    ref = mixed_reference()
    t = np.arange(ref.t0, ref.t_end + 1e-9, 0.005)
    x, y, th, _v, _ = ref.sample(t)
    step = np.hypot(np.diff(x), np.diff(y))
    assert np.all(step <= 0.1 * 0.005 + 1e-12)
    assert np.all(np.abs(np.diff(th)) <= 0.5 * 0.1 * 0.005 + 1e-12)
    assert np.sum(step) == pytest.approx(ref.length, rel=1e-4)
    g = ref.goal
    assert (x[-1], y[-1]) == pytest.approx((g[0], g[1]), abs=1e-9)


def test_cusp_dwell():
    dwell = 1.5
    ref = mixed_reference(dwell)
    t_cusp1 = 1.0 / 0.1 + 1.2 / 0.1  # end of the first pushing run
    t = np.linspace(t_cusp1 + 1e-6, t_cusp1 + dwell - 1e-6, 50)
    x, y, th, v, w = ref.sample(t)
    assert np.all(ref.direction_at(t) == REST)
    assert np.all(v == 0.0) and np.all(w == 0.0)
    assert np.ptp(x) == 0.0 and np.ptp(y) == 0.0 and np.ptp(th) == 0.0
    assert ref.direction_at(t_cusp1 - 1e-6)[0] == PUSH
    assert ref.direction_at(t_cusp1 + dwell + 1e-6)[0] == PULL
    expected_end = 2.2 / 0.1 + 0.8 / 0.05 + 0.7 / 0.1 + 1.0 / 0.1 + 2 * dwell
    assert ref.t_end == pytest.approx(expected_end)
    no_dwell = mixed_reference(0.0)
    assert no_dwell.t_end == pytest.approx(expected_end - 2 * dwell)


def test_sample_at_equals_sample():
    ref = mixed_reference()
    for t in np.linspace(ref.t0 - 3.0, ref.t_end + 3.0, 301):
        s = ref.sample_at(t)
        x, y, th, v, w = (a[0] for a in ref.sample(t))
        assert s[:5] == pytest.approx((x, y, th, v, w), abs=1e-12)
        assert s.direction == ref.direction_at(t)[0]


@pytest.mark.parametrize("kind", ["segments", "sampled"])
def test_sample_at_is_sample_bit_for_bit(kind):
    """The master samples step by step with sample_at; results must equal the array form."""
    ref = mixed_reference()
    if kind == "sampled":
        ref = SampledReference.from_reference(ref, 0.0123)
    rng = np.random.default_rng(3)
    t = np.concatenate((rng.uniform(ref.t0 - 2.0, ref.t_end + 2.0, 400),
                        ref.t0 + 0.005 * np.arange(int((ref.t_end - ref.t0) / 0.005) + 40)))
    columns = list(ref.sample(t)) + [ref.direction_at(t)]
    for k, tk in enumerate(t):
        assert tuple(ref.sample_at(tk)) == tuple(c[k] for c in columns), tk
