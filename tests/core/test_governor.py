"""The slip-aware governor: its force model against the FMU, the engine's governor against the
readable Python one (tests/reference/governor.py) bit for bit, and a manoeuvre it keeps from
sliding.
"""

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from reference import governor as readable

from pushtrain.cli.main import cli
from pushtrain.core.governor import GovernorConfig, SlipGovernor, lateral_forces
from pushtrain.core.kinematics import ChainGeometry
from pushtrain.cosim.fmu_slave import TrailerTrainSlave
from pushtrain.fmu.build import build_fmu

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "slip_governor.toml"


@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_the_governors_force_model_equals_the_fmus(n):
    rng = np.random.default_rng(n)
    fmu = build_fmu(n)
    for _ in range(4):
        front, rear = rng.uniform(0.3, 0.7, n), rng.uniform(0.3, 0.7, n)
        mass, inertia = rng.uniform(20, 60, n), rng.uniform(1, 5, n)
        theta = np.cumsum(rng.uniform(-0.6, 0.6, n + 1))
        v0, w0, v_cmd, w_cmd = rng.uniform(-0.2, 0.2, 4)
        start = {"v_start": v0, "w_start": w0, "robot_acc_max": 100.0, "robot_alpha_max": 100.0}
        for i in range(n):
            start.update({f"front[{i + 1}]": front[i], f"rear[{i}]": rear[i],
                          f"mass[{i + 1}]": mass[i], f"inertia[{i + 1}]": inertia[i]})
        start.update({f"theta_start[{i}]": theta[i] for i in range(n + 1)})
        with TrailerTrainSlave(fmu) as slave:
            slave.start(start)
            slave.real_writer(["v_cmd", "w_cmd"])([v_cmd, w_cmd])
            expected = slave.get_reals([f"F_lat[{i}]" for i in range(1, n + 1)])
        got = lateral_forces(theta[:-1] - theta[1:], v0, w0, (v_cmd - v0) / 0.05,
                             (w_cmd - w0) / 0.05, ChainGeometry(front, rear), mass, inertia)
        np.testing.assert_allclose(got, expected, rtol=1e-10, atol=1e-9)


def test_governed_commands_keep_the_predicted_forces_within_the_fraction():
    geom = ChainGeometry.uniform(3)
    cfg = GovernorConfig(geom, np.full(3, 42.1), np.full(3, 3.5083), np.full(3, 0.09), fraction=0.5)
    gov = SlipGovernor(cfg)
    rng = np.random.default_rng(0)
    phi = np.radians([20.0, -10.0, 15.0])
    for _ in range(200):  # random jumps of the command: many need limiting
        gov.limit(phi, rng.uniform(-0.15, 0.15), rng.uniform(-0.5, 0.5), 0.005)
    assert gov.limited > 0
    gov.reset()
    for _ in range(50):
        before = gov.estimate
        v, w = gov.limit(phi, 0.15, 0.5, 0.005)
        acc = (min(max((v - before[0]) / cfg.tau, -cfg.acc_max), cfg.acc_max),
               min(max((w - before[1]) / cfg.tau, -cfg.alpha_max), cfg.alpha_max))
        forces = lateral_forces(phi, *before, *acc, geom, cfg.mass, cfg.inertia)
        assert np.all(np.abs(forces) <= cfg.limits * (1 + 1e-9))


def test_the_manoeuvre_slides_without_the_governor_and_not_with_it(tmp_path):
    runs = {}
    for governor in (True, False):
        text = EXAMPLE.read_text().replace("governor = true", f"governor = {str(governor).lower()}")
        path = tmp_path / f"gov_{governor}.toml"
        path.write_text(text)
        out = tmp_path / f"out_{governor}"
        result = CliRunner().invoke(cli, ["plan-and-run", str(path), "--out", str(out),
                                          "--no-plots"])
        assert result.exit_code == 0, result.output
        runs[governor] = json.loads((out / "summary.json").read_text())
    with_gov, without = runs[True], runs[False]
    assert any(s["events"] for s in without["slip"])
    assert max(without["max_F_lat_ratio"]) >= 1.0 - 1e-9  # sliding at friction, never above
    assert not any(s["events"] for s in with_gov["slip"])
    assert max(with_gov["max_F_lat_ratio"]) <= 0.8 + 1e-6
    # what it costs: the goal is reached no later than 1 s after the ungoverned run
    assert with_gov["status"] == "goal_reached"
    assert with_gov["t_final"] <= without["t_final"] + 1.0


def test_the_engines_governor_equals_the_readable_one_bit_for_bit():
    """pt_governor_limit against the Python limit: every command, the estimates and the counts,
    over random chains, joints and command jumps (limited, bisected and held)."""
    rng = np.random.default_rng(12)
    counts = np.zeros(2)
    for n in (1, 3, 7):
        geom = ChainGeometry(rng.uniform(0.3, 0.7, n), rng.uniform(0.3, 0.7, n))
        cfg = GovernorConfig(geom, rng.uniform(30, 100, n), rng.uniform(1, 5, n),
                             rng.uniform(0.05, 0.2, n), fraction=float(rng.uniform(0.3, 1.0)))
        c_gov, py_gov = SlipGovernor(cfg), readable.SlipGovernor(cfg)
        c_gov.reset(0.05, -0.1)
        py_gov.reset(0.05, -0.1)
        for _ in range(300):
            phi = list(rng.uniform(-0.8, 0.8, n))
            v, w = rng.uniform(-0.3, 0.3), rng.uniform(-1.0, 1.0)
            assert c_gov.limit(phi, v, w, 0.005) == py_gov.limit(phi, v, w, 0.005)
            assert c_gov.estimate == (py_gov.v_est, py_gov.w_est)
        assert (c_gov.limited, c_gov.saturated) == (py_gov.limited, py_gov.saturated)
        counts += (c_gov.limited, c_gov.saturated)
    assert counts[0] > 100 and counts[1] > 0
