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
