"""Scenario model: the paper's defaults, plausible bounds shared with the FMU, cross-field rules."""

from __future__ import annotations

import math

import pytest
from click.testing import CliRunner

from pushtrain.cli.main import cli
from pushtrain.errors import ScenarioError
from pushtrain.limits import BOUNDS, SCENARIO_BOUNDS
from pushtrain.mission.scenario import parse_scenario

SCRIPTED = {
    "mission": {"kind": "scripted"},
    "start": {"x": 0.0, "y": 0.0},
    "reference": {"segments": [{"kind": "line", "length": 1.0}]},
}


def _with(path: str, value) -> dict:
    """SCRIPTED with ``path`` (dotted, e.g. ``train.mass``) set to ``value``."""
    data = {key: dict(section) for key, section in SCRIPTED.items()}
    *parents, leaf = path.split(".")
    target = data
    for part in parents:
        target[part] = dict(target.get(part, {}))
        target = target[part]
    target[leaf] = value
    return data


def _problems(data) -> list[tuple[str, object, str]]:
    with pytest.raises(ScenarioError) as info:
        parse_scenario(data, "test.toml")
    return info.value.errors


def test_a_minimal_scenario_gets_the_papers_table_1():
    sc = parse_scenario(SCRIPTED)
    t, r = sc.train, sc.robot
    assert (t.n, t.link, t.mass, t.mu, t.payload) == (3, 0.52, 42.1, 0.09, 0.0)
    # centroidal inertia of a 42.1 kg, 0.6 m x 0.8 m body: m (a^2 + b^2) / 12
    assert t.inertia == pytest.approx(42.1 * (0.6**2 + 0.8**2) / 12, abs=1e-4)
    assert (t.trailer_size.length, t.trailer_size.width) == (0.8, 0.6)
    assert sc.sim.step == 0.005
    assert r.v_max == 0.1 and math.radians(r.w_max_deg) == pytest.approx(0.1)
    assert t.phi_max_deg == 90.0
    assert (sc.controller.k_x, sc.controller.k_y, sc.controller.k_theta) == (1.0, 4.0, 4.0)
    assert sc.fmu.slip_mode == 0 and sc.fmu.max_substep == 0.005


# (scenario path, bound name, factor from the field's unit to the bound's unit)
BOUNDED_FIELDS = [
    ("train.link", "front", 1.0),
    ("train.mass", "mass", 1.0),
    ("train.inertia", "inertia", 1.0),
    ("train.payload", "payload", 1.0),
    ("train.mu", "mu", 1.0),
    ("robot.tau", "robot_tau", 1.0),
    ("robot.acc_max", "robot_acc_max", 1.0),
    ("robot.alpha_max_deg", "robot_alpha_max", math.pi / 180),
    ("robot.v_max", "robot.v_max", 1.0),
    ("robot.w_max_deg", "robot.w_max", math.pi / 180),
    ("fmu.max_substep", "max_substep", 1.0),
    ("sim.step", "sim.step", 1.0),
    ("sim.horizon", "sim.horizon", 1.0),
    ("controller.k_y", "controller.gain", 1.0),
    ("train.trailer_size", "body.size", 1.0),
]


def _value(path, bound_value, factor):
    if path == "train.trailer_size":
        return {"length": bound_value, "width": 0.6}
    return bound_value / factor


def _where(path):
    return "train.trailer_size.length" if path == "train.trailer_size" else path


@pytest.mark.parametrize("path, bound_name, factor", BOUNDED_FIELDS)
def test_each_bound_accepts_its_ends_and_rejects_beyond_them(path, bound_name, factor):
    bound = BOUNDS.get(bound_name) or SCENARIO_BOUNDS[bound_name]
    for end in (bound.lo, bound.hi):
        value = _value(path, end, factor)
        if path == "sim.horizon":
            value = 0.005 * round(value / 0.005) or 0.005
        if bound.lo == 0.0 and end == 0.0:
            parse_scenario(_with(path, value))  # zero is allowed where the range starts at 0
            continue
        parse_scenario(_with(path, value))
    beyond = [bound.hi * 1.5] + ([bound.lo * 0.5] if bound.lo > 0 else [])
    for out in beyond:
        problems = _problems(_with(path, _value(path, out, factor)))
        mine = [p for p in problems if p[0] == _where(path)]
        assert mine, problems
        assert bound.reason in mine[0][2] and "allowed" in mine[0][2]


def test_per_trailer_lists_are_checked_element_by_element():
    problems = _problems(_with("train.mass", [42.1, 1e6, 42.1]))
    assert [p[0] for p in problems] == ["train.mass[1]"]


def test_the_fmu_declares_the_same_bounds():
    import xml.etree.ElementTree as ET

    from pushtrain.fmu import render_model_description

    root = ET.fromstring(render_model_description(2, "{00000000-0000-0000-0000-000000000000}"))
    declared = {}
    for var in root.iter("ScalarVariable"):
        real = var.find("Real")
        if real is not None and "min" in real.attrib:
            declared[var.get("name").split("[")[0]] = (
                float(real.get("min")), float(real.get("max"))
            )
    for name in ("front", "rear", "mass", "inertia", "payload", "mu", "robot_tau", "max_substep"):
        assert declared[name] == (BOUNDS[name].lo, BOUNDS[name].hi), name


@pytest.mark.parametrize("text, field", [
    ("[train]\nphi_max_deg = 180\n", "train.phi_max_deg"),
    ("[train]\nphi_max_deg = 0\n", "train.phi_max_deg"),
    ("[train]\nn = 51\n", "train.n"),
    ("[sim]\nstep = 5.0\n", "sim.step"),
    ("[sim]\nhorizon = 1e9\n", "sim.horizon"),
    ("[sim]\nhorizon = 8.98846567431158e+305\n", "sim.horizon"),  # horizon / step overflows
    ("[sim]\nhorizon = 1.0\nstep = 0.003\n", "sim.horizon"),
    ("[fmu]\nslip_mode = 1\n[[events]]\ntype = 'slide'\nt = 1.0\nduration = 1.0\n"
     "distance = 0.1\ntrailer = 1\n", "events[0].type"),
])
def test_validate_exits_2_naming_the_field(tmp_path, text, field):
    base = ("[mission]\nkind = 'scripted'\n[start]\nx = 0.0\ny = 0.0\n"
            "[reference]\nsegments = [{kind = 'line', length = 1.0}]\n")
    path = tmp_path / "bad.toml"
    path.write_text(base + text)
    done = CliRunner().invoke(cli, ["validate", str(path)])
    assert done.exit_code == 2, done.output
    assert field in done.output and "Traceback" not in done.output


# The bound test above checks each field against the table it is computed from, so it cannot
# notice a wrong number in the table; these pin the ranges the table's reasons promise.
@pytest.mark.parametrize("path, value", [
    ("sim.step", 0.1), ("sim.step", 0.005), ("sim.step", 1e-4),
    ("train.mass", 2.0), ("train.mass", 5000.0), ("train.mu", 0.0), ("train.mu", 1.0),
    ("train.link", 0.05), ("train.link", 10.0), ("robot.tau", 0.001), ("robot.v_max", 5.0),
    ("robot.w_max_deg", 500.0), ("robot.alpha_max_deg", 5e5), ("controller.k_y", 1e3),
])
def test_plausible_values_are_accepted(path, value):
    parse_scenario(_with(path, value))


@pytest.mark.parametrize("path, value", [
    ("sim.step", 0.2),  # the chain moves further between two commands than can be corrected
    ("sim.step", 5e-5), ("train.mass", 0.5), ("train.mass", 2e4), ("train.mu", 2.5),
    ("train.link", 0.04), ("train.link", 11.0), ("robot.tau", 5e-4), ("robot.tau", 11.0),
    ("robot.v_max", 6.0), ("robot.w_max_deg", 600.0), ("controller.k_y", 2e3),
])
def test_implausible_values_are_refused_naming_the_field(path, value):
    problems = _problems(_with(path, value))
    assert [p[0] for p in problems] == [path], problems
    assert "allowed" in problems[0][2]


def test_event_trailers_and_joints_are_numbered_1_to_n():
    def events(**fields):
        if "trailer" in fields:
            kind = {"type": "slide", "t": 1.0, "duration": 1.0, "distance": 0.1}
        else:
            kind = {"type": "bias", "t": 1.0, "bias_deg": 2.0}
        return {**SCRIPTED, "train": {"n": 3}, "events": [{**kind, **fields}]}

    for fields in ({"trailer": 1}, {"trailer": 3}, {"joint": 1}, {"joint": 3}):
        parse_scenario(events(**fields))
    for fields, where in (({"trailer": 4}, "events[0].trailer"), ({"joint": 4}, "events[0].joint")):
        assert [p[0] for p in _problems(events(**fields))] == [where]
