"""Defaults are written once (``pushtrain/defaults.py``, ``pushtrain/table1.py``): no parameter
or field of the product's code (the engine, the co-simulation, the planner, ...) retypes one as
a number: the planner's closed-loop step and settle time (``ROLLOUT_STEP``,
``ROLLOUT_SETTLE_TIME``) and the pull guide's step (``PULL_GUIDE_STEP``) included.

A parameter default or a class field default whose name says which setting it is (``settle_time``,
``speed``, ``tau``, ...) must be the named constant, never a literal; the one packed layout of the
compiled instant's sample and command is written once."""

import ast
from pathlib import Path

import pytest

from pushtrain import defaults, table1

ROOT = Path(__file__).resolve().parents[2]
ROOMS = ("core", "cosim", "fmu", "mission", "planner", "facility", "report", "studies", "cli")
NAMED = {
    # parameter or field name -> the defaults it may only be spelled as
    "settle_time": (defaults.SETTLE_TIME, defaults.ROLLOUT_SETTLE_TIME),
    "guide_step": (defaults.PULL_GUIDE_STEP,),
    "speed": (defaults.REFERENCE_SPEED, 0.1),
    "cusp_dwell": (defaults.CUSP_DWELL,),
    "g": (defaults.GRAVITY,),
    "tau": (defaults.ROBOT_TAU,), "robot_tau": (defaults.ROBOT_TAU,),
    "acc_max": (defaults.ROBOT_ACC_MAX, defaults.ACC_MAX),
    "alpha_max": (defaults.ROBOT_ALPHA_MAX,),
    "fraction": (defaults.GOVERNOR_FRACTION,), "governor_fraction": (defaults.GOVERNOR_FRACTION,),
    "dt": (table1.SAMPLING_TIME,),
    "step": (table1.SAMPLING_TIME, defaults.PULL_GUIDE_STEP, defaults.ROLLOUT_STEP),
}
"""The settings checked, by the names they go by, with the values that would be a retyped copy
(the scenario's old 0.1 m/s reference speed too)."""


def _defaults_of(tree: ast.AST):
    """(name, default node) of every function parameter and class field with a default."""
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            args = node.args
            positional = args.posonlyargs + args.args
            for arg, default in zip(positional[len(positional) - len(args.defaults):],
                                    args.defaults, strict=True):
                yield arg.arg, default
            for arg, default in zip(args.kwonlyargs, args.kw_defaults, strict=True):
                if default is not None:
                    yield arg.arg, default
        elif isinstance(node, ast.ClassDef):
            for item in node.body:
                if (isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name)
                        and item.value is not None):
                    yield item.target.id, item.value


def _retyped(path: Path) -> list[str]:
    out = []
    for name, default in _defaults_of(ast.parse(path.read_text())):
        values = NAMED.get(name)
        if (values and isinstance(default, ast.Constant) and type(default.value) is float
                and default.value in values):
            out.append(f"{path.relative_to(ROOT)}:{default.lineno} {name} = {default.value!r}")
    return out


@pytest.mark.parametrize("room", ROOMS)
def test_no_default_is_retyped_as_a_number(room):
    found = [hit for path in sorted((ROOT / room).rglob("*.py")) for hit in _retyped(path)]
    assert not found, "write these as the constant of pushtrain.defaults or table1:\n" + "\n".join(
        found)


def test_the_check_would_catch_a_retyped_default(tmp_path):
    probe = ROOT / "core" / "_probe_defaults.py"
    probe.write_text("from dataclasses import dataclass\n\n\ndef f(settle_time=2.0, speed=0.1):\n"
                     "    pass\n\n\n@dataclass\nclass C:\n    tau: float = 0.05\n")
    try:
        found = _retyped(probe)
    finally:
        probe.unlink()
    assert len(found) == 3, found


def test_the_compiled_instants_packed_layout_is_written_once():
    """The layout of PtTrack's sample and command (``"@5di4x2d"``) is read in one place."""
    hits = [str(path.relative_to(ROOT)) for room in ROOMS
            for path in sorted((ROOT / room).rglob("*.py")) if '"@5di4x2d"' in path.read_text()]
    assert len(hits) <= 1, hits
