"""The import rules of DESIGN.md: who may import whom, and which folder owns which library."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {"fmu": "fmu", "planner": "planner", "cosim": "cosim", "cli": "cli"}


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: resolve against the file's subpackage
                pkg = f"pushtrain.{path.parent.name}"
                names.add(f"{pkg}.{node.module}" if node.module else pkg)
            elif node.module:
                names.add(node.module)
    return names


def _sources(folder: str):
    return sorted((ROOT / folder).rglob("*.py"))


@pytest.mark.parametrize("folder", sorted(PACKAGES))
def test_library_owners(folder):
    for path in _sources(folder):
        names = _imports(path)
        if any(n == "ompl" or n.startswith("ompl.") for n in names):
            assert folder == "planner", f"{path} imports ompl: only planner/ may"
        if any(n == "fmpy" or n.startswith("fmpy.") for n in names):
            assert folder in ("cosim", "fmu"), f"{path} imports fmpy: only cosim/ and fmu/ may"
        if folder != "cli":
            assert not any(n.startswith("pushtrain.cli") for n in names), f"{path} imports cli"


@pytest.mark.parametrize("modules, forbidden", [
    ("pushtrain.planner, pushtrain.cosim.controller, pushtrain.cosim.reference", "fmpy"),
    ("pushtrain.cosim.master, pushtrain.cosim.governor, pushtrain.fmu", "ompl"),
])
def test_transitive_imports_stay_apart(modules, forbidden):
    code = f"import sys, {modules}; assert {forbidden!r} not in sys.modules, {forbidden!r}"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_no_bare_top_level_modules_leak_from_the_install():
    code = ("import importlib.util as u;"
            "leaks = [m for m in ('planner', 'cli', 'cosim', 'fmu') if u.find_spec(m) is not None];"
            "print(leaks)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd="/")
    assert done.stdout.strip() == "[]", done.stdout + done.stderr
