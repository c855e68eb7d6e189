"""From a scenario to what the co-simulation gets (mission/runner.py): every field of the file
reaches the FMU, the controller, the sensors and the initial state, in SI units and radians.

These are the hand-offs a closed-loop run hides: a lag of 0.2 s instead of 0.05 s, a yaw
acceleration limit read as 30 rad/s^2 instead of 30 deg/s^2 or a seed that never reaches the
noise still lets the examples reach their goals. No co-simulation here: each test takes
milliseconds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pushtrain.core.sensors import Sensors
from pushtrain.fmu.variables import variables_for
from pushtrain.mission.runner import (
    controller_of,
    initial_of,
    plant_of,
    scripted_reference,
    sensors_of,
)
from pushtrain.mission.scenario import parse_scenario

SCRIPTED = {
    "mission": {"kind": "scripted"},
    "start": {"x": 1.0, "y": 2.0, "theta_deg": 180.0},
    "reference": {"segments": [{"kind": "line", "length": 2.0}]},
}


def _scenario(**sections):
    return parse_scenario({**SCRIPTED, **sections}, "test.toml")


def test_a_default_scenario_gives_the_fmu_its_own_defaults():
    """The scenario's defaults and the FMU's are both the paper's Table 1."""
    defaults = {v.name: v.start for v in variables_for(3)}
    sent = plant_of(_scenario()).start_values()
    for name in ("robot_tau", "robot_acc_max", "robot_alpha_max", "phi_max", "slip_mode",
                 "max_substep", "mass[1]", "mass[3]", "inertia[2]", "mu[3]", "front[1]",
                 "rear[0]"):
        assert sent[name] == pytest.approx(defaults[name], rel=1e-12), name


def test_the_robot_and_train_fields_reach_the_fmu_in_si_units():
    sc = _scenario(
        train={"n": 2, "mass": [40.0, 50.0], "inertia": 2.5, "payload": [0.0, 7.0], "mu": 0.3,
               "phi_max_deg": 60.0, "front": [0.5, 0.6], "rear": [0.4, 0.7]},
        robot={"tau": 0.2, "acc_max": 0.5, "alpha_max_deg": 30.0},
        fmu={"slip_mode": 1, "max_substep": 0.001},
    )
    sent = plant_of(sc).start_values()
    assert sent["robot_tau"] == 0.2
    assert sent["robot_acc_max"] == 0.5
    assert sent["robot_alpha_max"] == pytest.approx(math.radians(30.0))
    assert sent["phi_max"] == pytest.approx(math.radians(60.0))
    assert (sent["slip_mode"], sent["max_substep"]) == (1, 0.001)
    assert (sent["mass[1]"], sent["mass[2]"]) == (40.0, 50.0)
    assert (sent["payload[1]"], sent["payload[2]"]) == (0.0, 7.0)
    assert (sent["inertia[2]"], sent["mu[1]"], sent["mu[2]"]) == (2.5, 0.3, 0.3)
    assert (sent["front[1]"], sent["front[2]"], sent["rear[0]"], sent["rear[1]"]) == \
        (0.5, 0.6, 0.4, 0.7)


def test_the_controller_gets_the_scenarios_gains_limits_and_model():
    sc = _scenario(
        controller={"k_x": 0.5, "k_y": 6.0, "k_theta": 3.0, "model_link": 0.6, "acc_max": 0.3,
                    "alpha_max_deg": 20.0},
        robot={"v_max": 0.2, "w_max_deg": 11.0},
    )
    c = controller_of(sc)
    assert (c.k_x, c.k_y, c.k_theta) == (0.5, 6.0, 3.0)
    assert c.v_max == 0.2 and c.w_max == pytest.approx(math.radians(11.0))
    assert c.acc_max == 0.3 and c.alpha_max == pytest.approx(math.radians(20.0))
    assert np.allclose(c.geometry.front, 0.6) and np.allclose(c.geometry.rear, 0.6)


def test_joint_biases_reach_the_joint_readings_in_radians_with_their_sign():
    sc = _scenario(sensors={"joint_bias_deg": [1.0, -2.0, 3.0]})
    reading = Sensors(sensors_of(sc)).measure(0.0, 0.0, 0.0, np.zeros(3)).phi
    assert reading == pytest.approx(np.radians([1.0, -2.0, 3.0]), abs=1e-15)


def test_the_scenario_seed_drives_the_sensor_noise():
    def readings(seed):
        sc = _scenario(seed=seed, sensors={"joint_noise_deg": 1.0, "position_noise": 0.01})
        sensors = Sensors(sensors_of(sc))
        return np.concatenate([sensors.measure(0.0, 0.0, 0.0, np.zeros(3)).phi for _ in range(5)])

    assert np.array_equal(readings(1), readings(1))  # a run repeats exactly
    assert not np.allclose(readings(1), readings(2))  # another seed, other noise
    assert not np.allclose(readings(2), readings(3))


def test_the_start_offsets_and_joint_angles_are_degrees():
    sc = _scenario(start={"x": 1.0, "y": 2.0, "theta_deg": 180.0, "heading_offset_deg": 10.0,
                          "joint_angles_deg": [5.0, 0.0, -5.0]})
    initial = initial_of(sc, scripted_reference(sc))
    theta = np.asarray(initial.theta)
    assert theta[-1] == pytest.approx(math.radians(190.0))  # the last trailer
    # theta_{i-1} = theta_i + phi_i
    assert theta[:-1] - theta[1:] == pytest.approx(np.radians([5.0, 0.0, -5.0]))


def test_a_run_that_crosses_a_pillar_mid_way_is_a_collision(tmp_path):
    """straight_push with a thin pillar on the corridor's centre line half-way: the train runs
    through it and comes out clear, so its first and last poses are free; the check along the
    motion must still find the contact mid-run (exit 1, status collision)."""
    import json
    from pathlib import Path

    from click.testing import CliRunner

    from pushtrain.cli.main import cli

    example = Path(__file__).resolve().parents[2] / "examples" / "straight_push.toml"
    text = example.read_text()
    free = "free = [[-4.0, -1.0], [14.0, -1.0], [14.0, 1.0], [-4.0, 1.0]]"
    assert free in text
    pillar = "obstacles = [[[6.0, -0.05], [6.1, -0.05], [6.1, 0.05], [6.0, 0.05]]]"
    scenario = tmp_path / "pillar.toml"
    scenario.write_text(text.replace(free, free + "\n" + pillar))
    out = tmp_path / "out"
    done = CliRunner().invoke(cli, ["run", str(scenario), "--no-plots", "--out", str(out)])
    assert done.exit_code == 1, done.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "collision", summary["status"]
    first = min(summary["map_check"]["collisions"].values(), key=lambda c: c["t"])
    assert 5.0 < first["t"] < summary["t_final"] - 5.0  # mid-run, not at an end
    assert 5.5 < first["x"] < 7.5


def test_the_goal_heading_tolerance_reaches_the_master_in_radians():
    sc = _scenario(sim={"goal_tolerance": 0.07, "goal_heading_tolerance_deg": 9.0})
    from pushtrain.mission.runner import goal_tolerance_of

    position, heading = goal_tolerance_of(sc)
    assert position == 0.07
    assert heading == pytest.approx(9.0 * math.pi / 180.0)


def test_a_rotation_without_a_start_begins_at_the_origin_heading_east():
    sc = parse_scenario({"mission": {"kind": "rotation"}, "train": {"n": 2}}, "rot.toml")
    initial = initial_of(sc, None)
    assert (initial.x0, initial.y0) == (0.0, 0.0)
    assert np.array_equal(initial.theta, np.zeros(3))
