"""One definition per concept in the product: each of the engine's concepts has one class (its
Python face on the C), the names of the twins that were merged are gone, RK4 is written once in
the engine's C, and one control instant (sample the reference, lead the pull, command) is called
only through ``pt_instant``. The readable Python forms live in ``tests/reference/`` only."""

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ROOMS = ("pushtrain", "core", "fmu", "facility", "planner", "cosim", "report", "mission",
         "studies", "cli")
C_FOLDERS = ("core/csrc", "cosim/csrc", "fmu/controller_src")


def _classes() -> dict[str, list[str]]:
    found: dict[str, list[str]] = {}
    for room in ROOMS:
        for path in sorted((ROOT / room).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.ClassDef):
                    found.setdefault(node.name, []).append(str(path.relative_to(ROOT)))
    return found


CLASSES = _classes()


@pytest.mark.parametrize("name, home", [
    ("Reference", "core/reference.py"), ("PullGuide", "core/pulling.py"),
    ("Controller", "core/controller.py"), ("Tracker", "core/controller.py"),
    ("SlipGovernor", "core/governor.py"), ("Sensors", "core/sensors.py"),
    ("StepLoop", "cosim/step_loop.py"), ("Segment", "core/segment.py"),
    ("SampledReference", "core/sampled_reference.py"),
    ("Profile", "core/openloop.py"), ("RotationProfile", "core/openloop.py"),
])
def test_each_concept_has_one_class(name, home):
    assert CLASSES.get(name) == [home]


@pytest.mark.parametrize("gone", ["NativeReference", "NativeLeader", "NativeController",
                                  "PythonLoop", "CompiledLoop", "EngineStep", "TableSegment"])
def test_the_merged_twins_are_gone(gone):
    assert gone not in CLASSES


def _c_sources():
    for folder in C_FOLDERS:
        yield from sorted((ROOT / folder).glob("*.[ch]"))


def test_rk4_is_written_once_in_the_engines_c():
    """The RK4 combination ``h / 6.0 * (k1 + 2 k2 + 2 k3 + k4)`` appears once: core/csrc/ode.h."""
    hits = [str(p.relative_to(ROOT)) for p in _c_sources()
            for _ in re.findall(r"/ 6\.0 \* \(k1", p.read_text())]
    assert hits == ["core/csrc/ode.h"]


def test_one_control_instant_is_called_through_pt_instant():
    """Outside control.c no C samples the reference or the leader or calls the law itself: the
    master (step.c's pt_track), the rollout and the controller FMU call pt_instant."""
    wrong = [f"{p.relative_to(ROOT)} calls {name}" for p in _c_sources()
             if p.name not in ("control.c", "control.h")
             for name in ("pt_command", "pt_leader_sample")
             if re.search(rf"\b{name}\s*\(", p.read_text())]
    assert not wrong, wrong
    callers = {p.name for p in _c_sources() if re.search(r"\bpt_instant\s*\(", p.read_text())}
    assert {"rollout.c", "ctrl_model.c", "control.c"} <= callers


# A hitch link (a name with ``front`` or ``rear``) times the cos or sin of a heading, called or
# taken from an array of them (``c[..]``, ``cs[..]``, ``s``, ``sn``): a term of the bodies'
# positions P_i = P_{i-1} - R_{i-1} e_{i-1} - F_i e_i. The joints' velocity maps multiply links
# by the sin of a joint angle and a rate (``front[i] * s * w``), which this does not match.
LINK_TIMES_HEADING = re.compile(
    r"(front|rear)\w*(\[[^\]]*\])?\s*\*\s*(np\.|math\.)?(cos|sin|cs|sn|c|s)\b\s*([\[(;]|$)",
    re.MULTILINE)


def _link_terms(text: str) -> int:
    """Lines with such a term."""
    return sum(1 for line in text.splitlines() if LINK_TIMES_HEADING.search(line))


def test_body_positions_from_headings_are_written_once():
    """The bodies' positions from the headings are summed in one place, ``pt_chain_positions``
    in core/csrc/control.c (its x and y, from the robot and from the last trailer: four lines);
    every Python module calls its face ``core.kinematics.body_positions``. The report draws each
    trailer's hitch point from its own position (H_i = P_i + F_i e_i, two lines): not the
    chain's positions."""
    hits = {}
    for room in ROOMS:
        for path in sorted((ROOT / room).rglob("*.py")):
            if count := _link_terms(path.read_text()):
                hits[str(path.relative_to(ROOT))] = count
    for path in _c_sources():
        if count := _link_terms(path.read_text()):
            hits[str(path.relative_to(ROOT))] = count
    assert hits == {"core/csrc/control.c": 4, "report/geometry.py": 2}, hits
    body = re.search(r"void pt_chain_positions\(.*?\n}\n", (ROOT / "core/csrc/control.c")
                     .read_text(), re.DOTALL).group(0)
    assert _link_terms(body) == 4


@pytest.mark.parametrize("copy", [
    # the five copies this test replaced, as they were written
    "step_x = -geom.rear * c[:-1] - geom.front * c[1:]",
    "step_x = geometry.front * c[:, 1:] + geometry.rear * c[:, :-1]",
    "x -= rear[i] * math.cos(th[i]) + front[i] * math.cos(th[i + 1])",
    "x += self._front[i] * math.cos(th[i + 1]) + self._rear[i] * math.cos(th[i])",
    "bx[i] = bx[i - 1] - plant->rear[i - 1] * cs[i - 1] - plant->front[i - 1] * cs[i];",
    "        x -= chain->rear[i] * c;",
    "const double step_x = model->front[k] * cos(theta[k + 1]) + model->rear[k] * cos(theta[k]);",
])
def test_the_check_would_catch_another_copy(copy):
    assert _link_terms(copy) >= 1


@pytest.mark.parametrize("velocity", [
    "v, w[i] = c * v + front[i] * s * w[i + 1], (s * v - front[i] * c * w[i + 1]) / rear[i]",
    "v[i] = c[i - 1] * v[i - 1] + r * s[i - 1] * w[i - 1]",
    "const double v_new = c * v + f * s * w;",
])
def test_the_check_leaves_the_velocity_maps_alone(velocity):
    assert _link_terms(velocity) == 0
