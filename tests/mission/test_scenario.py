"""Scenario model: the paper's defaults, plausible bounds shared with the FMU, cross-field rules."""

from __future__ import annotations

import math

import numpy as np
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
    ("rotation.w_max_deg", "rotation.w_max", math.pi / 180),
    ("rotation.alpha_deg", "rotation.alpha", math.pi / 180),
    ("rotation.hold", "rotation.hold", 1.0),
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

    from pushtrain.fmu.render import render_model_description

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


@pytest.mark.parametrize("field, value", [
    ("alpha_deg", "1e-310"),  # w_max / alpha overflowed: the swing's table got t = inf
    ("alpha_deg", "1e308"), ("w_max_deg", "1e308"), ("w_max_deg", "1e-310"), ("hold", "1e308"),
])
def test_a_rotation_out_of_range_exits_2_naming_the_field_not_a_traceback(tmp_path, field, value):
    """plan-and-run of a rotation mission with an absurd (but positive, finite) yaw rate,
    acceleration or hold: exit 2 naming rotation.<field>, the value and the allowed range."""
    path = tmp_path / "rotation.toml"
    path.write_text(f"[mission]\nkind = 'rotation'\n[rotation]\n{field} = {value}\n"
                    "duration = 1.0\n")
    done = CliRunner().invoke(cli, ["plan-and-run", str(path), "--out", str(tmp_path / "o"),
                                    "--no-plots"])
    assert done.exit_code == 2, done.output
    assert f"rotation.{field} = {float(value):g}" in done.output, done.output
    assert "allowed" in done.output and "Traceback" not in done.output
    assert not (tmp_path / "o").exists()


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


# ---------------------------------------------------------------- issue #29, hardening round 3
def _validate(tmp_path, text: str):
    """``pushtrain validate`` of a scenario file with ``text``."""
    path = tmp_path / "case.toml"
    path.write_text(text)
    return CliRunner().invoke(cli, ["validate", str(path)])


SCRIPTED_TOML = ("[mission]\nkind = 'scripted'\n[start]\nx = 0.0\ny = 0.0\n"
                 "[reference]\nspeed = 0.08\n")


def test_a_scripted_line_longer_than_a_day_is_refused_naming_the_segment(tmp_path):
    """1e5 m at 0.08 m/s is 1.25e6 s, more than the 86 400 s a run may last: it passed
    validation and the run died with a 32 GiB ArrayMemoryError (1e9 m blamed 'horizon')."""
    for length in (1e5, 1e9):
        done = _validate(tmp_path, SCRIPTED_TOML
                         + f"segments = [{{kind = 'line', length = 1.0}}, "
                           f"{{kind = 'line', length = {length!r}}}]\n")
        assert done.exit_code == 2, done.output
        assert f"reference.segments[1].length = {length!r}" in done.output, done.output
        assert f"{length / 0.08:.6g} s" in done.output and "86400 s" in done.output
        assert "horizon" not in done.output and "Traceback" not in done.output
    # a segment's own speed is the one used: 1e4 m at 0.01 m/s is 1e6 s
    problems = _problems({**SCRIPTED, "reference": {"segments": [
        {"kind": "line", "length": 1e4, "speed": 0.01}]}})
    assert [p[0] for p in problems] == ["reference.segments[0].length"]
    assert "at 0.01 m/s it takes 1e+06 s" in problems[0][2]


def test_a_run_made_longer_than_a_day_by_many_segments_or_the_settling_is_refused():
    limit = SCENARIO_BOUNDS["sim.horizon"].hi
    # three segments of 0.4 day each (at 0.08 m/s): the run passes a day in the third
    length = 0.4 * limit * 0.08
    segs = [{"kind": "line", "length": length}] * 3
    problems = _problems({**SCRIPTED, "reference": {"segments": segs}})
    assert [p[0] for p in problems] == ["reference.segments[2].length"], problems
    # 0.9 day of reference plus 0.2 day of settling: the settling time is named
    problems = _problems({**SCRIPTED, "reference": {"segments": [
        {"kind": "line", "length": 0.9 * limit * 0.08}]}, "sim": {"settle_time": 0.2 * limit}})
    assert [p[0] for p in problems] == ["sim.settle_time"], problems
    # the same reference with a horizon of its own is a run of that horizon: accepted
    parse_scenario({**SCRIPTED, "reference": {"segments": [{"kind": "line", "length": 1e5}]},
                    "sim": {"horizon": 100.0}})
    # a rotation of 1e6 s is refused naming its duration
    problems = _problems({"mission": {"kind": "rotation"}, "rotation": {"duration": 1e6}})
    assert [p[0] for p in problems] == ["rotation.duration"], problems


def test_a_run_of_just_under_a_day_is_accepted():
    limit = SCENARIO_BOUNDS["sim.horizon"].hi
    parse_scenario({**SCRIPTED, "reference": {"segments": [
        {"kind": "line", "length": 0.99 * limit * 0.08 - 20.0 * 0.08}]}})


@pytest.mark.parametrize("text, where, shown", [
    ("[train]\nn = true\n", "train.n", "True"),
    ("[train]\nn = \"3\"\n", "train.n", "'3'"),
    ("[train]\nmass = true\n", "train.mass", "True"),
    ("[train]\nmass = [42.1, \"40\", 42.1]\n", "train.mass[1]", "'40'"),
    ("[sim]\nstep = \"0.005\"\n", "sim.step", "'0.005'"),
    ("seed = false\n", "seed", "False"),
    ("[fmu]\nslip_mode = true\n", "fmu.slip_mode", "True"),
    ("[planner]\nsmooth = 1\n", "planner.smooth", "1"),
    ("[[events]]\ntype = 'bias'\nt = 1.0\njoint = true\nbias_deg = 2.0\n", "events[0].joint",
     "True"),
])
def test_toml_booleans_and_strings_are_not_numbers(tmp_path, text, where, shown):
    """``n = true`` was read as 1 and ``n = "3"`` as 3 (and ``smooth = 1`` as true)."""
    done = _validate(tmp_path, SCRIPTED_TOML + "segments = [{kind = 'line', length = 1.0}]\n"
                     + text)
    assert done.exit_code == 2, done.output
    assert f"{where} = {shown}:" in done.output, done.output
    assert "Traceback" not in done.output


def test_whole_numbers_stay_numbers():
    """What strictness must not refuse: an int for a float, a whole float for an integer (a
    sweep's range gives 3.0 for train.n)."""
    sc = parse_scenario(_with("train.n", 3.0))
    assert sc.train.n == 3 and type(sc.train.n) is int
    assert parse_scenario(_with("train.mass", 42)).train.mass == 42.0
    assert parse_scenario(_with("sim.horizon", 10)).sim.horizon == 10.0
    assert [p[0] for p in _problems(_with("train.n", 2.5))] == ["train.n"]


def test_start_joint_angles_beyond_the_joint_limit_are_refused(tmp_path):
    """200 deg with phi_max = 90 deg passed validation and the run jackknifed at t = 0."""
    done = _validate(tmp_path, "[mission]\nkind = 'scripted'\n[train]\nn = 3\n[start]\n"
                     "x = 0.0\ny = 0.0\njoint_angles_deg = [0.0, 200.0, -10.0]\n"
                     "[reference]\nsegments = [{kind = 'line', length = 1.0}]\n")
    assert done.exit_code == 2, done.output
    assert "start.joint_angles_deg[1] = 200.0" in done.output and "90" in done.output
    start = {"x": 0.0, "y": 0.0}
    at_limit = {**SCRIPTED, "start": {**start, "joint_angles_deg": [90.0, -90.0, 0.0]}}
    parse_scenario(at_limit)  # the FMU's jackknife is |phi| > phi_max
    beyond = {**SCRIPTED, "train": {"phi_max_deg": 60.0},
              "start": {**start, "joint_angles_deg": [0.0, -61.0, 0.0]}}
    assert [p[0] for p in _problems(beyond)] == ["start.joint_angles_deg[1]"]


def test_events_after_the_end_of_the_run_are_refused(tmp_path):
    """An event at 1e6 s passed validation: it never happens."""
    event = "[[events]]\ntype = 'push'\nt = 1e6\nduration = 1.0\nlateral = 5.0\n"
    done = _validate(tmp_path, SCRIPTED_TOML + "segments = [{kind = 'line', length = 1.0}]\n"
                     + event)
    assert done.exit_code == 2, done.output
    # 1 m at 0.08 m/s plus the default 20 s of settling
    assert "events[0].t = 1000000.0" in done.output and "32.5 s" in done.output, done.output

    def push_at(t, **extra):
        return {**SCRIPTED, **extra, "events": [{"type": "push", "t": t, "duration": 1.0}]}

    parse_scenario(push_at(32.0))
    assert [p[0] for p in _problems(push_at(32.5))] == ["events[0].t"]
    # a longer sim.horizon lets the run go on (when the goal is late): the run may last that long
    parse_scenario(push_at(99.0, sim={"horizon": 100.0}))
    problems = _problems(push_at(150.0, sim={"horizon": 100.0}))
    assert [p[0] for p in problems] == ["events[0].t"] and "100 s" in problems[0][2]
    # a shorter one cuts the run on purpose (a look at its first seconds): allowed
    parse_scenario(push_at(20.0, sim={"horizon": 1.0}))
    assert [p[0] for p in _problems(push_at(40.0, sim={"horizon": 1.0}))] == ["events[0].t"]
    # a rotation lasts rotation.duration
    rotation = {"mission": {"kind": "rotation"}, "rotation": {"duration": 30.0}}
    parse_scenario({**rotation, "events": [{"type": "push", "t": 29.0, "duration": 1.0}]})
    problems = _problems({**rotation, "events": [{"type": "push", "t": 31.0, "duration": 1.0}]})
    assert [p[0] for p in problems] == ["events[0].t"] and "30 s" in problems[0][2]
    # a planned run's length is known only after planning: a day at most
    plan = {"map": {"bounds": [0.0, 0.0, 10.0, 10.0]}, "start": {"x": 1.0, "y": 1.0},
            "goal": {"x": 5.0, "y": 5.0}}
    parse_scenario({**plan, "events": [{"type": "push", "t": 3600.0, "duration": 1.0}]})
    problems = _problems({**plan, "events": [{"type": "push", "t": 1e6, "duration": 1.0}]})
    assert [p[0] for p in problems] == ["events[0].t"] and "86400 s" in problems[0][2]


def test_a_turning_radius_the_train_cannot_drive_is_refused(tmp_path):
    """turning_radius = 1e-6 m planned for 262 s. The smallest radius is where the steady
    joint angle 2 atan(D / r) (F = R = D) reaches phi_max: D / tan(phi_max / 2)."""
    base = ("[map]\nbounds = [0.0, 0.0, 10.0, 10.0]\n[start]\nx = 2.0\ny = 2.0\n"
            "[goal]\nx = 6.0\ny = 2.0\n")
    done = _validate(tmp_path, base + "[planner]\nturning_radius = 1e-6\n")
    assert done.exit_code == 2, done.output
    assert "planner.turning_radius = 1e-06" in done.output
    assert "0.52 m" in done.output and "phi_max_deg = 90" in done.output, done.output
    plan = {"map": {"bounds": [0.0, 0.0, 10.0, 10.0]}, "start": {"x": 2.0, "y": 2.0},
            "goal": {"x": 6.0, "y": 2.0}}
    for link, phi_max_deg in ((0.52, 90.0), (0.3, 120.0), (1.0, 40.0)):
        smallest = link / math.tan(math.radians(phi_max_deg) / 2.0)
        train = {"link": link, "phi_max_deg": phi_max_deg}
        parse_scenario({**plan, "train": train, "planner": {"turning_radius": 1.001 * smallest}})
        problems = _problems({**plan, "train": train,
                              "planner": {"turning_radius": 0.999 * smallest}})
        assert [p[0] for p in problems] == ["planner.turning_radius"]
        assert f"{smallest:.4g} m" in problems[0][2]


def _steady_angles_by_vectors(radius, front, rear):
    """Joint angles [rad] of the steady left turn with the last trailer's axle at (radius, 0)
    heading +y, built point by point: each body's heading e is square to its axle's position
    p = hitch + R e (a rigid rotation about the origin moves p along e), so
    hitch . e = -R: e at acos(-R / |hitch|) from the hitch's direction."""
    p, heading, angles = np.array([radius, 0.0]), math.pi / 2, []
    for f, r in zip(reversed(front), reversed(rear), strict=True):
        hitch = p + f * np.array([math.cos(heading), math.sin(heading)])
        if np.linalg.norm(hitch) < r:  # no heading keeps this body's axle square: no turn
            return [math.pi]
        psi = math.atan2(hitch[1], hitch[0]) + math.acos(-r / np.linalg.norm(hitch))
        e = np.array([math.cos(psi), math.sin(psi)])
        assert abs(np.dot(hitch + r * e, e)) < 1e-12
        angles.append(psi - heading)
        p, heading = hitch + r * e, psi
    return angles


def test_the_smallest_turning_radius_of_unequal_links_matches_the_geometry():
    from scipy.optimize import brentq

    from pushtrain.limits import min_turning_radius

    front, rear, phi_max = [0.3, 0.6, 0.2], [0.5, 0.4, 0.7], math.radians(80.0)
    expected = brentq(lambda r: max(_steady_angles_by_vectors(r, front, rear)) - phi_max,
                      0.6, 20.0, xtol=1e-12)
    assert min_turning_radius(front, rear, phi_max) == pytest.approx(expected, rel=1e-9)
    plan = {"map": {"bounds": [0.0, 0.0, 10.0, 10.0]}, "start": {"x": 2.0, "y": 2.0},
            "goal": {"x": 6.0, "y": 2.0},
            "train": {"front": front, "rear": rear, "phi_max_deg": 80.0}}
    parse_scenario({**plan, "planner": {"turning_radius": 1.001 * expected}})
    problems = _problems({**plan, "planner": {"turning_radius": 0.999 * expected}})
    assert [p[0] for p in problems] == ["planner.turning_radius"]


def test_a_value_out_of_its_range_is_reported_beside_schema_errors():
    """Every bad field at once: a file with train.n = 70 (schema), planner.time_budget = -1
    (schema) and sim.step = 5 s (its plausible range, checked on a whole model) lists all
    three; a combination that only the defaults of the refused fields would make wrong is not
    invented (train.mass with 70 values against the default n = 3 is not said)."""
    data = _with("train.n", 70)
    data["planner"] = {"time_budget": -1}
    data["sim"] = {"step": 5.0}
    data["train"]["mass"] = [42.1] * 70
    wheres = [where for where, _, _ in _problems(data)]
    assert wheres == ["train.n", "planner.time_budget", "sim.step"]
    # a bad type too; the range of another section still said
    data = _with("train.n", "three")
    data["robot"] = {"v_max": 50.0}
    wheres = [where for where, _, _ in _problems(data)]
    assert wheres == ["train.n", "robot.v_max"]
    # nothing else wrong: the schema error alone
    assert [w for w, _, _ in _problems(_with("train.n", 70))] == ["train.n"]
