"""Plausible parameter bounds (pushtrain.limits) and their use by the TrailerTrain FMU.

The FMU's min/max attributes and the C code's range checks are generated from the same table:
the XML must show its numbers and the FMU must refuse a value outside them with the very message
:func:`pushtrain.limits.check` gives.
"""

from __future__ import annotations

import dataclasses
import math

import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException

from pushtrain.fmu.variables import variables_for
from pushtrain.limits import BOUNDS, Bound, check

N = 3
INITIAL_CONDITIONS = {"theta_start", "x0_start", "y0_start", "v_start", "w_start"}


def _base(name: str) -> str:
    return name.split("[", 1)[0]


def test_bound_is_a_frozen_record_with_a_reason():
    bound = BOUNDS["front"]
    assert isinstance(bound, Bound) and bound.name == "front"
    with pytest.raises(dataclasses.FrozenInstanceError):
        bound.lo = 0.0
    for name, bound in BOUNDS.items():
        assert bound.name == name
        assert bound.lo < bound.hi and math.isfinite(bound.lo) and math.isfinite(bound.hi)
        assert len(bound.reason) > 20, name


@pytest.mark.parametrize("name, value", [("front", 0.52), ("mass[2]", 1.0), ("mass[2]", 10000.0),
                                         ("mu", 0.0), ("phi_max", math.pi)])
def test_check_accepts_values_in_the_closed_range(name, value):
    assert check(name, value) is None


def test_check_names_the_value_range_unit_and_reason():
    assert check("front[1]", 0.01) == (
        "front[1] = 0.01: allowed 0.05 to 10 m (a hitch link shorter than 5 cm or longer than "
        "10 m is not a trailer)")
    message = check("mu", 2.5)
    assert message.startswith("mu = 2.5: allowed 0 to 2 (")  # dimensionless: no unit
    assert "allowed 1 to 10000 kg" in check("mass", float("nan"))
    assert "not a number" in check("mass", True)
    assert "not a number" in check("mass", "42")
    with pytest.raises(KeyError, match="theta_start"):
        check("theta_start[1]", 0.0)


@pytest.fixture(scope="module")
def model_description(built_fmu):
    return read_model_description(str(built_fmu(N)))


def test_xml_bounds_are_the_table(model_description):
    bounded = set()
    for var in model_description.modelVariables:
        bound = BOUNDS.get(_base(var.name))
        if bound is None:
            continue
        bounded.add(_base(var.name))
        assert var.causality == "parameter", var.name
        assert (float(var.min), float(var.max)) == (bound.lo, bound.hi), var.name
        assert (var.unit or "") == bound.unit, var.name
        assert bound.contains(float(var.start)), var.name  # the defaults are plausible
    assert bounded == set(BOUNDS)


def test_every_parameter_is_bounded_except_the_initial_conditions():
    """A new physical parameter needs a bound in pushtrain/limits.py."""
    unbounded = {_base(v.name) for v in variables_for(N)
                 if v.causality == "parameter" and v.min is None}
    assert unbounded == INITIAL_CONDITIONS


def _outside(bound: Bound) -> list[float]:
    below = bound.lo - max(abs(bound.lo) * 0.5, 1e-3)
    return [below, bound.hi * 1.5]


def _last_element(name: str) -> str:
    """The FMU variable of parameter ``name`` with the highest index (the scalar itself)."""
    return [v.name for v in variables_for(N) if _base(v.name) == name][-1]


CASES = [(_last_element(name), value) for name, bound in BOUNDS.items()
         for value in _outside(bound)]


@pytest.mark.parametrize("when", ["before_enter", "after_enter"])
@pytest.mark.parametrize("name, value", CASES)
def test_fmu_refuses_a_value_outside_its_bound_with_the_same_message(built_fmu_sim, name, value,
                                                                     when):
    sim = built_fmu_sim(N, logging_on=True)
    with pytest.raises(FMICallException) as info:
        if when == "before_enter":
            sim.initialize(params={name: value})
        else:
            sim.initialize(after_enter={name: value})
    assert info.value.function == "fmi2ExitInitializationMode"
    errors = [message for status, _, message in sim.messages if status >= 3]
    assert errors == [f"fmi2ExitInitializationMode: {check(name, value)}"]


def test_fmu_accepts_every_bound_itself(built_fmu_sim):
    for limit in ("lo", "hi"):
        values = {}
        for var in variables_for(N):
            bound = BOUNDS.get(_base(var.name))
            if bound is not None:
                values[var.name] = getattr(bound, limit)
        sim = built_fmu_sim(N, logging_on=True)
        sim.initialize(params=values)
        assert [m for s, _, m in sim.messages if s >= 3] == [], limit
