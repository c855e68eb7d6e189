"""Tests of a reference given as samples (pushtrain.core.sampled_reference)."""

import numpy as np
import pytest

from pushtrain.core.reference import Reference
from pushtrain.core.sampled_reference import SampledReference
from pushtrain.core.segment import PULL, PUSH, Segment
from pushtrain.errors import ReferencePathError


def test_sampled_reference_reproduces_the_analytic_one():
    ref = Reference.from_segments(
        (0.3, -0.2, 0.4),
        [Segment("line", 1.0), Segment("arc", 1.2, 0.5),
         Segment("arc", 0.8, -0.3, direction=PULL, speed=0.05),
         Segment("line", 0.7, direction=PULL), Segment("arc", 1.0, 0.4)],
        speed=0.1, cusp_dwell=1.5)
    sampled = SampledReference.from_reference(ref, 0.01)
    assert sampled.t_end == pytest.approx(ref.t_end, abs=0.01)
    assert sampled.length == pytest.approx(ref.length, rel=1e-4)
    t = np.linspace(ref.t0, ref.t_end - 0.02, 777)
    for a, b in zip(sampled.sample(t), ref.sample(t), strict=True):
        np.testing.assert_allclose(a[1:-1], b[1:-1], atol=2e-3)
    for tk in (3.0, 30.0, 45.0, 60.0):
        assert sampled.sample_at(tk)[:3] == pytest.approx(ref.sample_at(tk)[:3], abs=1e-5)
        assert sampled.sample_at(tk).direction == ref.sample_at(tk).direction


def _sampled_line(m=200, dt=0.01, speed=0.1):
    t = dt * np.arange(m)
    x = -speed * t
    return dict(
        t=t,
        x=x,
        y=np.zeros(m),
        theta=np.zeros(m),
        v=np.full(m, -speed),
        w=np.zeros(m),
        direction=np.full(m, PUSH),
    )


def test_sampled_reference_detects_jumps():
    SampledReference(**_sampled_line())  # the clean line is accepted
    bad = _sampled_line()
    bad["y"][100:] += 0.05  # 5 cm lateral step
    with pytest.raises(ReferencePathError, match="position jumps"):
        SampledReference(**bad)
    bad = _sampled_line()
    bad["theta"][50:] += 0.2
    with pytest.raises(ReferencePathError, match="heading jumps"):
        SampledReference(**bad)
    bad = _sampled_line()
    bad["t"][10] = bad["t"][9]
    with pytest.raises(ReferencePathError, match="strictly increase"):
        SampledReference(**bad)
    bad = _sampled_line()
    bad["direction"][20] = PULL
    with pytest.raises(ReferencePathError, match="contradicts direction"):
        SampledReference(**bad)
    bad = _sampled_line()
    bad["x"][5] = np.nan
    with pytest.raises(ReferencePathError, match="finite"):
        SampledReference(**bad)


def test_sampled_reference_unwraps_headings():
    m, dt, w = 400, 0.01, 0.5
    t = dt * np.arange(m)
    theta = np.pi - 0.5 + w * t  # crosses pi
    kappa = 2.0
    speed = w / kappa
    x = -(np.sin(theta) - np.sin(theta[0])) / kappa
    y = (np.cos(theta) - np.cos(theta[0])) / kappa
    wrapped = np.mod(theta + np.pi, 2 * np.pi) - np.pi
    ref = SampledReference(t, x, y, wrapped, np.full(m, -speed), np.full(m, w), np.full(m, PUSH))
    assert ref.sample_at(3.5).theta == pytest.approx(theta[350], abs=1e-9)
