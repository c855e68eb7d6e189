"""Sweep specs read numbers as strictly as scenarios (issue #29, case 9): a TOML boolean or
string is not a number, and a swept value keeps its type into the scenario it sets."""

from __future__ import annotations

import pytest

from pushtrain.errors import SweepError
from pushtrain.studies.sweep_spec import parse_sweep_spec

RANGE = {"path": "controller.k_y", "range": {"start": 1.0, "stop": 2.0, "num": 3}}
UNIFORM = {"path": "controller.k_y", "dist": "uniform", "low": 1.0, "high": 2.0}


@pytest.mark.parametrize("data, where", [
    ({"parameters": [{**RANGE, "range": {"start": 1.0, "stop": 2.0, "num": True}}]},
     "parameters[0].range.num"),
    ({"parameters": [{**RANGE, "range": {"start": 1.0, "stop": 2.0, "num": "3"}}]},
     "parameters[0].range.num"),
    ({"parameters": [{**RANGE, "range": {"start": True, "stop": 2.0, "num": 3}}]},
     "parameters[0].range.start"),
    ({"mode": "monte_carlo", "samples": "5", "parameters": [UNIFORM]}, "samples"),
    ({"mode": "monte_carlo", "samples": 5, "parameters": [{**UNIFORM, "low": "1"}]},
     "parameters[0].low"),
    ({"seed": True, "parameters": [RANGE]}, "seed"),
    ({"chunk_size": True, "parameters": [RANGE]}, "chunk_size"),
    ({"seed_per_run": 1, "parameters": [RANGE]}, "seed_per_run"),
    ({"steady_window": "10", "parameters": [RANGE]}, "steady_window"),
])
def test_booleans_and_strings_are_not_numbers(data, where):
    with pytest.raises(SweepError) as err:
        parse_sweep_spec(data, "spec.toml")
    assert [w for w, _, _ in err.value.errors] == [where], err.value.errors
    assert "not the boolean" in str(err.value) or "not a string" in str(err.value) \
        or "not the number" in str(err.value)


def test_whole_numbers_and_typed_values_pass():
    spec = parse_sweep_spec({"chunk_size": 4.0, "parameters": [
        {**RANGE, "range": {"start": 1, "stop": 2, "num": 3.0}},
        {"path": "train.n", "values": [2, True, "3"]}]})
    assert spec.chunk_size == 4 and spec.parameters[0].range.num == 3
    # values are passed on as written: the scenario then refuses true and "3" for train.n
    assert [type(v) for v in spec.parameters[1].values] == [int, bool, str]


def test_a_swept_boolean_is_refused_by_the_scenario_naming_the_run(tmp_path):
    from pushtrain.mission.scenario import parse_scenario
    from pushtrain.studies.sweep_runs import prepare_runs

    base = parse_scenario({"mission": {"kind": "scripted"}, "start": {"x": 0.0, "y": 0.0},
                           "reference": {"segments": [{"kind": "line", "length": 1.0}]}})
    spec = parse_sweep_spec({"parameters": [{"path": "train.n", "values": [2, True]}]})
    with pytest.raises(SweepError) as err:
        prepare_runs(base, spec)
    assert "train.n = True" in str(err.value) and "not the boolean true" in str(err.value)


@pytest.mark.parametrize("values, grid", [(5, 3), (7, 1), (1, 4)])
def test_a_sweep_of_exactly_max_total_runs_is_allowed_and_one_more_is_refused(values, grid):
    """The limit is inclusive: ``max_total = N`` allows N runs (a grid of values x grid)."""
    from pushtrain.studies.sweep_spec import check_size, count_runs

    spec = parse_sweep_spec({"parameters": [
        {"path": "controller.k_y", "values": [float(v) for v in range(1, values + 1)]},
        {"path": "controller.k_theta", "values": [float(v) for v in range(1, grid + 1)]}]},
        "spec.toml")
    n = values * grid
    assert count_runs(spec) == n
    assert check_size(spec, n) == n
    assert check_size(spec, None) == n
    with pytest.raises(SweepError, match=f"more than the limit of {n - 1} runs"):
        check_size(spec, n - 1)
