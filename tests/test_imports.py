"""The architecture as import rules: one direction of arrows, no cycles, one owner per library.

The rooms (folders mapped into ``pushtrain.*``) and what each may import::

    cli -> {mission, studies, report, planner, cosim, fmu, core}
    studies -> {mission, report, planner, cosim, fmu, core}
    mission -> {planner, cosim, fmu, core}
    planner -> core            cosim -> {core, fmu}         report -> core
    core, fmu -> (nothing of pushtrain but the infrastructure in pushtrain/)

Every room may import ``pushtrain`` itself (errors, files, validation, limits). Deprecated
aliases of moved modules are left out: they exist only to forward old import paths.
"""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

from pushtrain._compat import MOVED_MODULES

ROOT = Path(__file__).resolve().parents[1]
ROOMS = ("pushtrain", "core", "fmu", "planner", "cosim", "report", "mission", "studies", "cli")
ALLOWED = {
    "pushtrain": set(),
    "core": set(),
    "fmu": set(),
    "planner": {"core"},
    "cosim": {"core", "fmu"},
    "report": {"core"},
    "mission": {"core", "fmu", "planner", "cosim"},
    "studies": {"core", "fmu", "planner", "cosim", "report", "mission"},
    "cli": {"core", "fmu", "planner", "cosim", "report", "mission", "studies"},
}
OWNERS = {"ompl": {"planner"}, "fmpy": {"cosim", "fmu"}, "dask": {"studies.sweep"},
          "distributed": {"studies.sweep"}, "ezdxf": {"planner.dxf"}}
DEPRECATED = set(MOVED_MODULES) | {"pushtrain.planner.errors"}


def _module_name(path: Path) -> str:
    room = path.relative_to(ROOT).parts[0]
    parts = [] if room == "pushtrain" else [room]
    parts += list(path.relative_to(ROOT / room).with_suffix("").parts)
    if parts and parts[-1] == "__init__":
        parts.pop()
    return ".".join(["pushtrain", *parts])


def _is_package(path: Path) -> bool:
    return path.name == "__init__.py"


def _imports(path: Path) -> set[str]:
    """Every module the file imports, anywhere in it (function-level imports included)."""
    module = _module_name(path)
    package = module if _is_package(path) else module.rpartition(".")[0]
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            names.add(target)
            # ``from pkg import sub`` imports the submodule pkg.sub when it is one
            names |= {f"{target}.{alias.name}" for alias in node.names}
    return names


def _sources():
    for room in ROOMS:
        for path in sorted((ROOT / room).rglob("*.py")):
            if _module_name(path) not in DEPRECATED:
                yield room, path


MODULES = {_module_name(path): path for _, path in _sources()}


def _room_of(module: str) -> str | None:
    """The room of a pushtrain module, or None for a third-party one."""
    parts = module.split(".")
    if parts[0] != "pushtrain":
        return None
    if len(parts) > 1 and parts[1] in ROOMS[1:]:
        return parts[1]
    return "pushtrain"


def _internal_edges():
    for room, path in _sources():
        for target in _imports(path):
            if target in MODULES:
                yield room, path, target


def test_every_room_is_walked():
    assert {room for room, _ in _sources()} == set(ROOMS)
    assert len(MODULES) >= 35


@pytest.mark.parametrize("room", ROOMS)
def test_arrows_point_one_way(room):
    wrong = [f"{path.relative_to(ROOT)} imports {target}"
             for r, path, target in _internal_edges()
             if r == room and _room_of(target) not in ALLOWED[room] | {room, "pushtrain"}]
    assert not wrong, "\n".join(wrong)


def test_no_import_cycles():
    graph = {name: set() for name in MODULES}
    for _, path, target in _internal_edges():
        source = _module_name(path)
        if target != source and not source.startswith(target + "."):  # a package's own __init__
            graph[source].add(target)
    # Tarjan's strongly connected components
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    assert not cycles, f"import cycles: {cycles}"


@pytest.mark.parametrize("library", sorted(OWNERS))
def test_one_owner_per_library(library):
    wrong = []
    for room, path in _sources():
        module = _module_name(path).removeprefix("pushtrain.")
        if any(n == library or n.startswith(library + ".") for n in _imports(path)):
            if not any(module == owner or module.startswith(owner + ".") or room == owner
                       for owner in OWNERS[library]):
                wrong.append(str(path.relative_to(ROOT)))
    assert not wrong, f"{library} imported outside {sorted(OWNERS[library])}: {wrong}"


def test_the_rules_would_catch_a_forbidden_arrow(tmp_path):
    """The walker sees relative, absolute and function-level imports."""
    probe = ROOT / "core" / "_probe_for_test.py"
    probe.write_text(
        "def f():\n    from ..planner import world\n    import pushtrain.cosim.master\n"
    )
    try:
        found = _imports(probe)
    finally:
        probe.unlink()
    assert {"pushtrain.planner.world", "pushtrain.cosim.master"} <= found


@pytest.mark.parametrize("modules, forbidden", [
    ("pushtrain.planner, pushtrain.core.controller, pushtrain.core.reference", "fmpy"),
    ("pushtrain.cosim.master, pushtrain.core.governor, pushtrain.fmu", "ompl"),
    ("pushtrain.core.controller, pushtrain.core.pulling, pushtrain.core.analysis",
     "pushtrain.planner"),
    ("pushtrain.cli.main", "distributed"),
])
def test_transitive_imports_stay_apart(modules, forbidden):
    code = f"import sys, {modules}; assert {forbidden!r} not in sys.modules, {forbidden!r}"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_no_bare_top_level_modules_leak_from_the_install():
    code = ("import importlib.util as u;"
            "leaks = [m for m in ('planner', 'cli', 'cosim', 'fmu', 'core', 'mission', 'studies',"
            " 'report') if u.find_spec(m) is not None];"
            "print(leaks)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd="/")
    assert done.stdout.strip() == "[]", done.stdout + done.stderr


@pytest.mark.parametrize("old", sorted(MOVED_MODULES))
def test_old_import_paths_work_with_a_warning(old):
    code = ("import warnings, importlib; warnings.simplefilter('error', DeprecationWarning)\n"
            f"try:\n    importlib.import_module({old!r})\n"
            "except DeprecationWarning as w:\n    print('warned:', w)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert f"warned: {old} moved to {MOVED_MODULES[old]}" in done.stdout, done.stdout + done.stderr
    code = (f"import warnings; warnings.simplefilter('ignore')\nimport importlib\n"
            f"old = importlib.import_module({old!r}); new = importlib.import_module("
            f"{MOVED_MODULES[old]!r})\nassert old is new")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
