"""The master with the compiled control law against the readable reference law
(``tests/reference/controller.py``).

The C path samples the reference, the pull leader and computes the command in one call
(``pt_track``); it must give the master's run with the reference law passed in built, bit for
bit. The law has no other implementation to choose: a scenario's ``controller.implementation``
is an unknown key.
"""

import math

import numpy as np
import pytest
from click.testing import CliRunner
from reference.controller import BackwardController

from pushtrain.cli.main import cli
from pushtrain.core.controller import Controller, ControllerConfig
from pushtrain.core.governor import GovernedController, GovernorConfig, SlipGovernor
from pushtrain.core.kinematics import ChainGeometry
from pushtrain.core.reference import Reference
from pushtrain.core.segment import PULL, PUSH, REST, Segment
from pushtrain.core.sensors import Measurement, SensorConfig
from pushtrain.core.tracking import TrackingLoop
from pushtrain.cosim.events import SetBias
from pushtrain.cosim.master import simulate
from pushtrain.errors import ControllerError


def _push_pull():
    """Push a line and an arc, cusp (dwell), pull a line and an arc, cusp, push again."""
    return Reference.from_segments((0.0, 0.0, math.pi), [
        Segment("line", 0.4), Segment("arc", 0.5, 0.8), Segment("line", 0.4, 0.0, PULL),
        Segment("arc", 0.4, -0.7, PULL), Segment("line", 0.3)], speed=0.08, cusp_dwell=1.0)


def _config(geometry=None):
    geometry = geometry or ChainGeometry.uniform(3, 0.52)
    return ControllerConfig(geometry=geometry, k_x=1.0, k_y=4.0, k_theta=4.0, v_max=0.1,
                            w_max=0.1, acc_max=0.2, alpha_max=math.radians(10.0))


def _same_runs(a, b):
    assert a.status == b.status and a.message == b.message
    assert a.data.dtype == b.data.dtype and len(a.data) == len(b.data)
    for name in a.data.dtype.names:
        assert np.array_equal(a.data[name], b.data[name], equal_nan=True), name


def _runs(fmu, ref, sensors=None, **kwargs):
    """The master's runs with the compiled law (a ControllerConfig) and with the reference law
    (built), keyed "c" and "python"."""
    return {impl: simulate(fmu, ref, law, sensors, check_goal=False, **kwargs)
            for impl, law in (("c", _config()), ("python", BackwardController(_config())))}


def test_c_and_python_master_runs_are_bit_identical_on_a_push_pull_mission(fmu3):
    ref = _push_pull()
    runs = _runs(fmu3, ref, events=[SetBias(6.0, 2, math.radians(3.0))])
    d = runs["c"].data
    # the mission has what it is meant to test: pushing, pulling, dwells, active rate limits
    assert {PUSH, PULL, REST} <= set(d["direction"].astype(int).tolist())
    assert np.abs(np.diff(d["w_cmd"])).max() == pytest.approx(math.radians(10.0) * 0.005,
                                                              rel=1e-9)
    _same_runs(runs["c"], runs["python"])


def test_c_and_python_agree_with_noisy_sensors_a_pose_fix_and_the_governor(fmu3):
    ref = _push_pull()
    sensors = SensorConfig(n_joints=3, joint_noise=math.radians(0.2),
                           position_noise=0.002, heading_noise=math.radians(0.2),
                           localize="last_trailer", seed=7)
    runs = _runs(fmu3, ref, sensors, horizon=30.0)
    _same_runs(runs["c"], runs["python"])

    def governed(cls):
        gov = SlipGovernor(GovernorConfig(_config().geometry, np.full(3, 42.1), np.full(3, 3.5),
                                          np.full(3, 0.09), fraction=0.8, tau=0.05, acc_max=1.0,
                                          alpha_max=2.0))
        return GovernedController(cls(_config()), gov, dt=0.005)

    runs = {cls: simulate(fmu3, ref, governed(cls), horizon=30.0, check_goal=False)
            for cls in (Controller, BackwardController)}
    _same_runs(runs[Controller], runs[BackwardController])


def test_the_c_path_takes_one_call_per_instant_and_equals_the_python_loop():
    """pt_track (reference sample + leader + command) against TrackingLoop with the Python
    controller, on measured states around the reference, pushing, resting and pulling."""
    geom = ChainGeometry(np.array([0.5, 0.6, 0.45]), np.array([0.3, 0.52, 0.7]))
    ref = _push_pull()
    c_loop = TrackingLoop(Controller(_config(geom)), ref)
    py_loop = TrackingLoop(BackwardController(_config(geom)), ref)
    assert c_loop.tracker is not None and py_loop.tracker is None  # the one-call path is used
    for loop in (c_loop, py_loop):
        loop.controller.reset(0.0, 0.0, -0.05)
    rng = np.random.default_rng(3)
    seen = set()
    for t in np.arange(0.0, ref.t_end + 2.0, 0.05):
        r = ref.sample_at(t)
        phi = rng.normal(0.0, 0.1, 3)
        last = (r.x + rng.normal(0, 0.02), r.y + rng.normal(0, 0.02), r.theta + 0.05)
        meas = Measurement(r.x + 1.5 + rng.normal(0, 0.05), r.y + rng.normal(0, 0.05),
                           r.theta + rng.normal(0, 0.1), phi.tolist(),
                           last if rng.random() < 0.3 else None)
        got, want = c_loop.command(t, meas), py_loop.command(t, meas)
        seen.add(want[3].direction)
        assert got[3] == want[3]  # the reference sample, bit for bit
        assert got[2].mode == want[2].mode
        np.testing.assert_allclose(got[:2], want[:2], rtol=0, atol=1e-12)
        np.testing.assert_allclose(got[2][1:], want[2][1:], rtol=0, atol=1e-12)
    assert seen == {PUSH, PULL, REST}


def test_the_law_has_no_implementation_to_choose(fmu3, tmp_path):
    """The compiled law is the product's only one: simulate has no ``implementation`` and a
    scenario's ``controller.implementation`` is refused as an unknown key."""
    with pytest.raises(TypeError, match="implementation"):
        simulate(fmu3, _push_pull(), _config(), implementation="c")
    path = tmp_path / "bad.toml"
    path.write_text('[mission]\nkind = "scripted"\n[controller]\nimplementation = "c"\n'
                    '[reference]\nsegments = [{kind = "line", length = 1.0}]\n'
                    '[start]\nx = 0.0\ny = 0.0\n')
    result = CliRunner().invoke(cli, ["plan-and-run", str(path), "--out", str(tmp_path / "o")])
    assert result.exit_code == 2, result.output
    assert "controller.implementation" in result.output, result.output
    assert "Traceback" not in result.output


def test_the_c_path_refuses_what_the_python_path_refuses():
    ref = _push_pull()
    loop = TrackingLoop(Controller(_config()), ref)
    with pytest.raises(ControllerError, match="3"):
        loop.command(1.0, Measurement(2.0, 0.0, math.pi, [0.0, 0.0]))
    with pytest.raises(ControllerError, match="non-finite measurement"):
        loop.command(1.0, Measurement(math.nan, 0.0, math.pi, [0.0, 0.0, 0.0]))
    # a pulling instant without a pull guide (a controller without guide_geometry)
    t_pull = next(t for t in np.arange(0.0, ref.t_end, 0.05)
                  if ref.sample_at(t).direction == PULL)
    bare = Controller(_config())
    command = bare.tracker(ref, None).command
    with pytest.raises(ControllerError, match="leader"):
        command(t_pull, Measurement(2.0, 0.0, math.pi, [0.0, 0.0, 0.0]))
    v, w, info, sample = command(0.5, Measurement(2.0, 0.0, math.pi, [0.0, 0.0, 0.0]))
    assert sample == ref.sample_at(0.5) and info.mode == "push"
