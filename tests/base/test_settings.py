"""Settings written once: a scenario section is generated from its library config's fields."""

import dataclasses
import math

import pytest

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.kinematics import ChainGeometry
from pushtrain.core.sensors import SensorConfig
from pushtrain.cosim.plant import PlantConfig
from pushtrain.errors import ScenarioError
from pushtrain.mission.scenario import (
    ControllerSection,
    FmuSection,
    PlannerSection,
    RobotSection,
    SensorSection,
    TrainSection,
    parse_scenario,
)
from pushtrain.planner.config import PlannerConfig
from pushtrain.settings import config_values, file_keys

SECTIONS = [
    (PlannerConfig, PlannerSection, None, {}, set()),
    (SensorConfig, SensorSection, None, {"n_joints": 3}, set()),
    (ControllerConfig, ControllerSection, None, {"geometry": ChainGeometry.uniform(3)},
     {"model_link", "governor", "governor_fraction"}),
    (ControllerConfig, RobotSection, "robot", {"geometry": ChainGeometry.uniform(3)},
     {"tau", "acc_max", "alpha_max_deg"}),
    (PlantConfig, RobotSection, "robot", {"n_trailers": 3}, {"v_max", "w_max_deg"}),
    (PlantConfig, TrainSection, "train", {"n_trailers": 3},
     {"n", "link", "front", "rear", "trailer_size", "robot_size"}),
    (PlantConfig, FmuSection, "fmu", {"n_trailers": 3}, {"fmi_version"}),
]
"""Each library config, its scenario section, the part of the config the section holds, the
arguments that come from elsewhere, and the section's own fields that feed no library config."""


@pytest.mark.parametrize(("config", "section", "part", "required", "own"), SECTIONS)
def test_a_default_file_gives_the_library_defaults(config, section, part, required, own):
    """No default can drift: the config made from an empty section equals the default config,
    field by field."""
    made = config(**required, **config_values(config, section(), part))
    default = config(**required)
    for name in file_keys(config, part):
        assert getattr(made, name) == getattr(default, name), name


@pytest.mark.parametrize(("config", "section", "part", "required", "own"), SECTIONS)
def test_the_section_has_exactly_the_file_settings(config, section, part, required, own):
    keys = {k.key for k in file_keys(config, part).values()}
    assert set(section.model_fields) == keys | own and not keys & own


def test_the_robot_section_defaults_are_the_fmus():
    """The robot's velocity loop: the file's defaults are the plant FMU's start values."""
    from pushtrain.fmu.variables import scalars_for

    start = {v.name: v.start for v in scalars_for(2)}
    robot = RobotSection()
    assert (robot.tau, robot.acc_max, math.radians(robot.alpha_max_deg)) == pytest.approx(
        (start["robot_tau"], start["robot_acc_max"], start["robot_alpha_max"]), rel=1e-15)


def test_angles_are_degrees_in_the_file_and_radians_in_the_library():
    section = PlannerSection(pull_max_phi_deg=20.0, joint_margin_deg=3.0, goal_max_phi_deg=10.0,
                             clearance=[0.1, 0.2])
    config = PlannerConfig(**config_values(PlannerConfig, section))
    assert config.pull_max_phi == math.radians(20.0)
    assert config.joint_margin == math.radians(3.0)
    assert config.goal_max_phi == math.radians(10.0)
    assert config.clearance == (0.1, 0.2)


def test_every_file_field_reaches_the_config():
    """A value set in the file arrives in the planner's config (none is dropped on the way)."""
    changed = {"time_budget": 3.5, "turning_radius": 1.7, "transient_margin": 0.3,
               "anytime_time": 0.2, "inflation": 0.07, "speed": 0.06, "cusp_dwell": 2.0,
               "pull_start_tolerance": 0.3, "clearance": 0.08, "joint_margin_deg": 4.0,
               "pull_max_phi_deg": 12.0, "step_length": 0.4, "search_weight": 1.5,
               "smooth": False, "goal_max_phi_deg": 7.0, "planner": "rrtconnect"}
    assert set(changed) == set(PlannerSection.model_fields)
    config = PlannerConfig(**config_values(PlannerConfig, PlannerSection(**changed)))
    default = PlannerConfig()
    for f in dataclasses.fields(PlannerConfig):
        if f.name in file_keys(PlannerConfig):
            assert getattr(config, f.name) != getattr(default, f.name), f.name


def test_every_sensor_field_reaches_the_sensor_model():
    """The walk of joint_bias_deg and its neighbours: file (degrees) -> SensorConfig (radians)
    -> the model the C reads (its bias array)."""
    from pushtrain.core.sensors import Sensors
    from pushtrain.mission.runner import sensors_of

    data = {"mission": {"kind": "scripted"}, "start": {"x": 0.0, "y": 0.0},
            "reference": {"segments": [{"kind": "line", "length": 1.0}]},
            "sensors": {"joint_bias_deg": [1.0, -2.0, 3.0], "joint_noise_deg": 0.5,
                        "joint_quantization_deg": 0.1, "joint_backlash_deg": 0.2,
                        "position_noise": 0.01, "heading_noise_deg": 0.3,
                        "localize": "last_trailer"}}
    assert set(data["sensors"]) == set(SensorSection.model_fields)
    config = sensors_of(parse_scenario(data))
    assert config.joint_bias == tuple(math.radians(a) for a in (1.0, -2.0, 3.0))
    assert (config.joint_noise, config.joint_quantization, config.joint_backlash,
            config.heading_noise) == tuple(math.radians(a) for a in (0.5, 0.1, 0.2, 0.3))
    assert config.position_noise == 0.01 and config.measure_last_pose
    sensors = Sensors(config)
    assert list(sensors.bias) == [math.radians(a) for a in (1.0, -2.0, 3.0)]
    assert sensors.model.measure_last_pose == 1


def test_the_time_budget_default_is_one_value():
    """The issue's example of a drifted default: 1.0 s in the file, 2.0 s in the library."""
    assert PlannerSection().time_budget is PlannerConfig().time_budget is None


def test_a_bad_generated_field_still_names_the_field():
    data = {"planner": {"pull_max_phi_deg": -1.0, "planner": "astar"}}
    with pytest.raises(ScenarioError) as err:
        parse_scenario(data)
    text = str(err.value)
    assert "planner.pull_max_phi_deg" in text and "planner.planner" in text


def test_the_docs_state_table_1_as_pushtrain_table1_holds_it():
    """The README's scenario section quotes Table 1: the numbers are pushtrain.table1's."""
    from pathlib import Path

    from pushtrain import table1

    readme = Path(__file__).resolve().parents[2].joinpath("README.md").read_text()
    section = readme.split("## Scenario files", 1)[1].split("\n## ", 1)[0]
    for text in (f"{table1.TRAILER_MASS:g} kg", f"D = {table1.LINK:g} m",
                 f"{table1.TRAILER_LENGTH:g} m x {table1.TRAILER_WIDTH:g} m",
                 f"mu = {table1.MU:g}", f"{table1.SAMPLING_TIME * 1000:g} ms step"):
        assert text in section, text


def test_the_scenario_defaults_are_table_1():
    from pushtrain import table1
    from pushtrain.mission.scenario import FmuSection, SimSection, TrainSection

    train = TrainSection()
    assert (train.mass, train.link, train.inertia, train.mu) == (
        table1.TRAILER_MASS, table1.LINK, table1.TRAILER_INERTIA, table1.MU)
    assert (train.trailer_size.length, train.trailer_size.width) == (
        table1.TRAILER_LENGTH, table1.TRAILER_WIDTH)
    assert SimSection().step == FmuSection().max_substep == table1.SAMPLING_TIME
