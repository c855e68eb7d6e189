"""Error handling of the TrailerTrain FMU and its builder.

Bad parameters give fmi2Error in fmi2ExitInitializationMode with a logged message naming the
variable and its value; parameters set after fmi2EnterInitializationMode are honoured; a state
driven non-finite gives fmi2Error, never NaN outputs.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from pushtrain.core.kinematics import ChainGeometry, body_positions
from pushtrain.errors import FmuBuildError, FmuInputError
from pushtrain.fmu.build import build_fmu

N = 3
STATUS_ERROR = 3

OUTPUT_BLOCKS = ("x", "y", "theta", "phi", "v", "w", "F_lat", "hitch_fx", "hitch_fy")

BAD_PARAMETERS = [
    ("front[1]", 0.0, "0"),
    ("front[3]", -0.25, "-0.25"),
    ("rear[0]", -0.25, "-0.25"),
    ("rear[2]", 0.0, "0"),
    ("front[2]", math.nan, "nan"),
    ("mass[2]", 0.0, "0"),
    ("mass[1]", -42.5, "-42.5"),
    ("inertia[3]", 0.0, "0"),
    ("inertia[1]", -1.5, "-1.5"),
    ("payload[2]", -5.5, "-5.5"),
    ("mu[1]", -0.125, "-0.125"),
    ("robot_tau", 0.0, "0"),
    ("robot_tau", -0.5, "-0.5"),
    ("robot_acc_max", 0.0, "0"),
    ("robot_acc_max", -2.5, "-2.5"),
    ("robot_alpha_max", 0.0, "0"),
    ("robot_alpha_max", -0.75, "-0.75"),
    ("phi_max", 0.0, "0"),
    ("phi_max", -1.25, "-1.25"),
    ("max_substep", 0.0, "0"),
    ("max_substep", -0.005, "-0.005"),
]


def error_messages(sim):
    return [message for status, _, message in sim.messages if status >= STATUS_ERROR]


def outputs_finite(sim) -> bool:
    return all(np.all(np.isfinite(sim.array(block))) for block in OUTPUT_BLOCKS)


@pytest.mark.parametrize("when", ["before_enter", "after_enter"])
@pytest.mark.parametrize("name, value, text", BAD_PARAMETERS)
def test_bad_parameter_fails_exit_initialization_with_message(built_fmu_sim, name, value, text,
                                                              when):
    sim = built_fmu_sim(N, logging_on=True)
    values = {name: value}
    with pytest.raises(FMICallException) as info:
        if when == "before_enter":
            sim.initialize(params=values)
        else:
            sim.initialize(after_enter=values)
    assert info.value.function == "fmi2ExitInitializationMode"
    assert info.value.status >= STATUS_ERROR
    messages = error_messages(sim)
    assert any(name in m and text in m.lower() for m in messages), messages


@pytest.mark.parametrize("value, text", [(2, "2"), (-1, "-1")])
def test_unknown_slip_mode_is_an_error(built_fmu_sim, value, text):
    sim = built_fmu_sim(N, logging_on=True)
    with pytest.raises(FMICallException):
        sim.initialize(params={"slip_mode": value})
    assert any("slip_mode" in m and text in m for m in error_messages(sim)), sim.messages


def test_slip_mode_1_initializes_and_its_substep_is_checked(built_fmu_sim):
    sim = built_fmu_sim(N, logging_on=True)
    sim.initialize(params={"slip_mode": 1})  # sliding wheels are implemented
    assert not error_messages(sim)
    bad = built_fmu_sim(N, logging_on=True)
    with pytest.raises(FMICallException):
        bad.initialize(params={"slip_mode": 1, "slip_substep": 0.0})
    assert any("slip_substep" in m and "0" in m for m in error_messages(bad)), bad.messages


SLIDE_WITH_SLIP_MODE_1 = {
    "slip_mode_first": [{"slip_mode": 1}, {"slide[2]": 0.1}],
    "slide_first": [{"slide[2]": 0.1}, {"slip_mode": 1}],
}


@pytest.mark.parametrize("when", ["before_enter", "after_enter"])
@pytest.mark.parametrize("order", sorted(SLIDE_WITH_SLIP_MODE_1))
def test_slide_with_slip_mode_1_fails_at_exit_whatever_the_order(built_fmu_sim, order, when):
    """Each set is accepted; the combination is refused once, naming both variables."""
    sim = built_fmu_sim(N, logging_on=True)
    sim.fmu.setupExperiment(startTime=0.0)
    if when == "after_enter":
        sim.fmu.enterInitializationMode()
    for values in SLIDE_WITH_SLIP_MODE_1[order]:
        sim.set(values)  # no error at the set
    assert error_messages(sim) == []
    if when == "before_enter":
        sim.fmu.enterInitializationMode()
    with pytest.raises(FMICallException) as info:
        sim.fmu.exitInitializationMode()
    assert info.value.function == "fmi2ExitInitializationMode"
    (message,) = error_messages(sim)
    assert "slip_mode = 1" in message and "slide[2] = 0.1" in message, message


@pytest.mark.parametrize("order", sorted(SLIDE_WITH_SLIP_MODE_1))
def test_a_combination_corrected_before_exit_is_accepted(built_fmu_sim, order):
    sim = built_fmu_sim(N, logging_on=True)
    sim.fmu.setupExperiment(startTime=0.0)
    sim.fmu.enterInitializationMode()
    for values in SLIDE_WITH_SLIP_MODE_1[order] + [{"slide[2]": 0.0}]:
        sim.set(values)  # one call each, in this order
    sim.fmu.exitInitializationMode()
    assert error_messages(sim) == []
    assert sim.get(["slip_mode"]) == [1]


def test_slide_with_slip_mode_0_is_accepted_in_both_orders(built_fmu_sim):
    for params in ({"slip_mode": 0, "slide[2]": 0.1}, {"slide[2]": 0.1, "slip_mode": 0}):
        sim = built_fmu_sim(N, logging_on=True)
        sim.initialize(params)
        sim.step(0.01)
        assert error_messages(sim) == []
        assert sim.real("slide_speed[2]") == 0.1


def test_good_parameters_log_no_error(built_fmu_sim):
    sim = built_fmu_sim(N, logging_on=True)
    sim.initialize(params={"payload[1]": 0.0, "mu[2]": 0.0, "front[1]": 0.3})
    assert error_messages(sim) == []


def test_parameters_set_after_enter_initialization_are_honoured(built_fmu_sim):
    """libcosim and other FMIL importers set parameters in Initialization Mode."""
    geom = ChainGeometry(np.array([0.7, 0.45, 0.6]), np.array([0.35, 0.8, 0.52]))
    theta = np.array([0.4, 0.1, -0.3, 0.2])
    late = {f"front[{i}]": float(geom.front[i - 1]) for i in range(1, N + 1)}
    late.update({f"rear[{k}]": float(geom.rear[k]) for k in range(N)})
    late.update({f"theta_start[{i}]": float(t) for i, t in enumerate(theta)})
    late.update({"x0_start": 1.5, "y0_start": -2.0, "v_start": -0.2, "w_start": 0.1,
                 "mass[2]": 80.0, "payload[2]": 20.0, "mu[2]": 0.2, "g": 9.0,
                 "phi_max": 0.35})
    sim = built_fmu_sim(N)
    sim.initialize(after_enter=late)
    x_ref, y_ref = body_positions(1.5, -2.0, theta, geom)
    np.testing.assert_allclose(sim.array("x"), x_ref, atol=1e-12)
    np.testing.assert_allclose(sim.array("y"), y_ref, atol=1e-12)
    assert sim.real("v[0]") == -0.2 and sim.real("w[0]") == 0.1
    assert sim.real("F_lat_max[2]") == pytest.approx(0.2 * 100.0 * 9.0, rel=1e-12)
    assert sim.get(["jackknifed"]) == [True]  # |phi[2]| = 0.4 > 0.35
    # the robot speed stays v_start while the command equals it: start values took effect
    sim.set({"v_cmd": -0.2, "w_cmd": 0.1})
    sim.step(0.1)
    assert sim.real("v[0]") == pytest.approx(-0.2, abs=1e-15)


def _run_until_error(sim, steps, h):
    """Step; return the first FMICallException, asserting finite outputs while none occurred."""
    for _ in range(steps):
        try:
            sim.step(h)
        except FMICallException as error:
            return error
        assert outputs_finite(sim), {b: sim.array(b) for b in OUTPUT_BLOCKS}
    return None


def test_state_overflow_gives_error_not_nan(built_fmu_sim):
    sim = built_fmu_sim(N, logging_on=True)
    sim.initialize({"v_start": 1e308}, {"v_cmd": 1e308})
    assert outputs_finite(sim)
    error = _run_until_error(sim, 5, 10.0)  # x0 reaches 1e309 = inf in the first step
    assert error is not None, "an overflowing state must give fmi2Error"
    assert error.status >= STATUS_ERROR
    assert error_messages(sim)


def test_output_overflow_gives_error_not_nan(built_fmu_sim):
    """Centripetal terms R w0^2 overflow: either init or the first step must fail."""
    sim = built_fmu_sim(N, logging_on=True)
    try:
        sim.initialize({"w_start": 1e200}, {"w_cmd": 1e200})
    except FMICallException as error:
        assert error.status >= STATUS_ERROR
        assert error_messages(sim)
        return
    assert outputs_finite(sim), "non-finite outputs after fmi2ExitInitializationMode"
    error = _run_until_error(sim, 3, 0.01)
    assert error is not None and error.status >= STATUS_ERROR


NON_FINITE_INPUTS = [("v_cmd", math.nan, "nan"), ("v_cmd", math.inf, "inf"),
                     ("w_cmd", -math.inf, "-inf"), ("push_x", math.nan, "nan"),
                     ("push_y", math.inf, "inf"), ("slide[2]", math.inf, "inf")]


@pytest.mark.parametrize("mode", ["initialization", "stepping"])
@pytest.mark.parametrize("name, value, text", NON_FINITE_INPUTS)
def test_set_real_itself_refuses_a_non_finite_input(built_fmu_sim, name, value, text, mode):
    """fmi2SetReal returns fmi2Error for the call that passes the value, naming input and value;
    the refused value is not stored and the outputs stay finite."""
    sim = built_fmu_sim(N, logging_on=True)
    if mode == "initialization":
        sim.fmu.setupExperiment(startTime=0.0)
        sim.fmu.enterInitializationMode()
    else:
        sim.initialize({"theta_start[1]": 0.2}, {"v_cmd": -0.1, "w_cmd": 0.05})
        sim.step(0.01)
    before = sim.real(name)
    with pytest.raises(FMICallException) as info:
        sim.fmu.setReal([sim.vr(name)], [value])
    assert info.value.function == "fmi2SetReal" and info.value.status == STATUS_ERROR
    assert error_messages(sim) == [f"fmi2SetReal: input {name} = {text}: must be finite"]
    assert sim.real(name) == before  # readable after the error, and unchanged
    if mode == "stepping":
        assert outputs_finite(sim)


@pytest.mark.parametrize("n_trailers", [0, 51, -3])
def test_build_fmu_rejects_n_out_of_range(n_trailers, tmp_path):
    # a bad request is an input error (a ValueError); a compiler failure is not
    assert issubclass(FmuInputError, ValueError) and not issubclass(FmuBuildError, ValueError)
    with pytest.raises(FmuInputError, match=str(n_trailers)):
        build_fmu(n_trailers, tmp_path / "x.fmu")
    assert not (tmp_path / "x.fmu").exists()
