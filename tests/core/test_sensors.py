"""Tests of the sensor models (pushtrain.core.sensors)."""

import numpy as np
import pytest
from reference.sensors import ReferenceSensors

from pushtrain.core.sensors import Measurement, SensorConfig, Sensors
from pushtrain.errors import SensorError

NOISY = dict(joint_noise=0.01, position_noise=0.02, heading_noise=0.005)


def run(sensors, steps=50, n=3):
    out = []
    for k in range(steps):
        phi = 0.1 * np.sin(0.1 * k + np.arange(n))
        m = sensors.measure(1.0 + k, 2.0, 0.3, phi)
        out.append(np.concatenate(([m.x0, m.y0, m.theta0], m.phi)))
    return np.array(out)


def test_seeded_reproducibility():
    a = run(Sensors(SensorConfig(3, seed=7, **NOISY)))
    b = run(Sensors(SensorConfig(3, seed=7, **NOISY)))
    c = run(Sensors(SensorConfig(3, seed=8, **NOISY)))
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    s = Sensors(SensorConfig(3, seed=7, **NOISY))
    first = run(s)
    s.reset()
    np.testing.assert_array_equal(run(s), first)


def test_bias_is_applied_exactly_and_can_be_switched_on():
    bias = np.array([0.01, -0.02, 0.03])
    s = Sensors(SensorConfig(3, joint_bias=bias))
    phi = np.array([0.2, -0.1, 0.05])
    m = s.measure(0.5, -0.5, 1.0, phi)
    assert isinstance(m, Measurement) and m.last_pose is None
    np.testing.assert_array_equal(m.phi, phi + bias)
    assert (m.x0, m.y0, m.theta0) == (0.5, -0.5, 1.0)
    s.set_bias(3, np.radians(10.0))
    m = s.measure(0.5, -0.5, 1.0, phi)
    np.testing.assert_array_equal(m.phi, phi + [0.01, -0.02, np.radians(10.0)])
    np.testing.assert_array_equal(s.bias, [0.01, -0.02, np.radians(10.0)])
    s.reset()
    np.testing.assert_array_equal(s.bias, bias)
    scalar = Sensors(SensorConfig(2, joint_bias=0.05))
    np.testing.assert_array_equal(
        scalar.measure(0, 0, 0, [0.0, 0.1]).phi, np.array([0.0, 0.1]) + 0.05
    )


def test_quantization():
    q = np.radians(0.5)
    s = Sensors(SensorConfig(2, joint_quantization=q))
    rng = np.random.default_rng(1)
    for _ in range(200):
        phi = rng.uniform(-1, 1, 2)
        meas = s.measure(0, 0, 0, phi).phi
        steps = meas / q
        np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)
        assert np.all(np.abs(meas - phi) <= 0.5 * q + 1e-12)


def test_backlash_is_a_dead_band():
    b = 0.02
    s = Sensors(SensorConfig(1, joint_backlash=b))
    assert s.measure(0, 0, 0, [0.0]).phi[0] == 0.0  # starts at the first true angle
    # moving up: the reading lags by b/2 once the play is taken up
    assert s.measure(0, 0, 0, [0.005]).phi[0] == 0.0  # inside the band: no change
    assert s.measure(0, 0, 0, [0.05]).phi[0] == pytest.approx(0.05 - b / 2)
    # reversing: nothing happens until the joint has moved back by the band width b
    assert s.measure(0, 0, 0, [0.05 - 0.015]).phi[0] == pytest.approx(0.05 - b / 2)
    assert s.measure(0, 0, 0, [0.05 - b]).phi[0] == pytest.approx(0.05 - b / 2)
    assert s.measure(0, 0, 0, [0.0]).phi[0] == pytest.approx(0.0 + b / 2)
    # the error is bounded by b/2 on any path
    s.reset()
    path = 0.2 * np.sin(np.linspace(0, 20, 500))
    readings = np.array([s.measure(0, 0, 0, [p]).phi[0] for p in path])
    assert np.max(np.abs(readings - path)) <= b / 2 + 1e-12
    assert np.max(np.abs(readings - path)) > 0.45 * b


def test_noise_statistics():
    cfg = SensorConfig(4, joint_bias=0.1, seed=3, **NOISY)
    s = Sensors(cfg)
    m = 20000
    phi = np.array([0.1, 0.2, -0.3, 0.0])
    data = np.array(
        [
            np.concatenate(([r.x0, r.y0, r.theta0], r.phi))
            for r in (s.measure(1.0, 2.0, 0.5, phi) for _ in range(m))
        ]
    )
    err = data - np.concatenate(([1.0, 2.0, 0.5], phi + 0.1))
    std = np.array([0.02, 0.02, 0.005, 0.01, 0.01, 0.01, 0.01])
    # mean within 4 standard errors, std within 3 %
    assert np.all(np.abs(err.mean(axis=0)) < 4 * std / np.sqrt(m))
    np.testing.assert_allclose(err.std(axis=0), std, rtol=0.03)
    # independent channels
    corr = np.corrcoef(err.T)
    assert np.max(np.abs(corr - np.eye(7))) < 0.04


def test_last_pose_measurement():
    s = Sensors(SensorConfig(2, localize="last_trailer"))
    m = s.measure(0.0, 0.0, 0.0, [0.0, 0.0], last_pose=(-2.08, 0.0, 0.0))
    assert m.last_pose == (-2.08, 0.0, 0.0)
    with pytest.raises(SensorError, match="last_pose"):
        s.measure(0.0, 0.0, 0.0, [0.0, 0.0])


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(n_joints=0), "n_joints"),
        (dict(n_joints=3, joint_bias=[0.1, 0.2]), "joint_bias"),
        (dict(n_joints=3, joint_noise=-1.0), "joint_noise"),
        (dict(n_joints=3, joint_quantization=np.nan), "joint_quantization"),
        (dict(n_joints=3, joint_backlash=-0.1), "joint_backlash"),
        (dict(n_joints=3, position_noise=-0.1), "position_noise"),
        (dict(n_joints=3, seed=-2), "seed"),
    ],
)
def test_bad_config_raises(kwargs, field):
    with pytest.raises(SensorError, match=field):
        SensorConfig(**kwargs)


def test_bad_calls_raise():
    s = Sensors(SensorConfig(3))
    with pytest.raises(SensorError, match="joint"):
        s.set_bias(0, 0.1)
    with pytest.raises(SensorError, match="joint"):
        s.set_bias(4, 0.1)
    with pytest.raises(SensorError, match="finite"):
        s.set_bias(1, np.inf)
    with pytest.raises(SensorError, match="shape"):
        s.measure(0, 0, 0, [0.1, 0.2])


@pytest.mark.parametrize("kwargs", [
    {}, dict(joint_noise=0.01), dict(joint_quantization=0.001),
    dict(joint_backlash=0.01), dict(position_noise=0.01), dict(heading_noise=0.01),
    dict(localize="last_trailer", position_noise=0.02),
    dict(joint_noise=0.004, joint_quantization=0.002, joint_backlash=0.03,
         position_noise=0.02, heading_noise=0.01, localize="last_trailer")])
def test_compiled_model_equals_the_numpy_reference_bit_for_bit(kwargs):
    """core/csrc/sensors.c against tests/reference/sensors.py: the same readings and poses, bit
    for bit, through bias switches, backlash reversals, quantization ties and a reset."""
    config = SensorConfig(3, joint_bias=[0.01, -0.02, 0.03], seed=11, **kwargs)
    compiled = Sensors(config)
    for _ in range(2):  # a run, then the same run after reset()
        reference = ReferenceSensors(config)
        for k in range(300):
            phi = 0.2 * np.sin(0.05 * k + np.arange(3)) + 0.0005 * (k % 7)
            if k == 150:
                compiled.set_bias(2, 0.07)
                reference.set_bias(2, 0.07)
            if k % 50 == 3:  # a tie of the quantizer: round half to even
                phi = np.array([0.0005, 0.0015, -0.0025]) - [0.01, -0.02, 0.03]
            last = (1.0 - 0.01 * k, -0.5, 0.3 + 0.001 * k)
            got = compiled.measure(0.5 + 0.01 * k, -0.5, 1.0, phi, last)
            want = reference.measure(0.5 + 0.01 * k, -0.5, 1.0, phi, last)
            assert got.phi.tobytes() == want.phi.tobytes(), k
            assert (got.x0, got.y0, got.theta0, got.last_pose) == (
                want.x0, want.y0, want.theta0, want.last_pose), k
        compiled.reset()


def test_a_nan_joint_angle_reads_nan_with_play_too():
    """As numpy.clip: a NaN true angle is not hidden by the play (the law then refuses it)."""
    s = Sensors(SensorConfig(2, joint_backlash=0.02))
    s.measure(0, 0, 0, [0.0, 0.0])
    assert np.isnan(s.measure(0, 0, 0, [np.nan, 0.0]).phi[0])


def test_measurer_writes_the_readings_where_it_is_told():
    s = Sensors(SensorConfig(2, joint_bias=0.1, localize="last_trailer"))
    truth, out = np.array([1.0, 2.0, 0.5, -1.0, 2.0, 0.4, 0.2, -0.1]), np.zeros(2)
    m = s.measurer(truth, out)()
    assert out.tolist() == m.phi == [0.2 + 0.1, -0.1 + 0.1]
    assert (m.x0, m.y0, m.theta0, m.last_pose) == (1.0, 2.0, 0.5, (-1.0, 2.0, 0.4))
    with pytest.raises(SensorError, match="shape"):
        s.measurer(truth[:5], out)
