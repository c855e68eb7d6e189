"""The architecture as import rules: one direction of arrows, no cycles, one owner per library.

The rooms (folders mapped into ``pushtrain.*``) and what each may import::

    cli -> {mission, studies, report, ros, planner, facility, cosim, fmu, core}
    ros -> {mission, planner, facility, cosim, core}
    studies -> {mission, report, planner, facility, cosim, fmu, core}
    mission -> {planner, facility, cosim, fmu, core}
    planner -> {facility, core}     report -> {facility, core}     cosim -> {core, fmu}
    facility -> core     fmu -> core (its controller FMU only: the engine's C files and Segment)
    core -> (nothing of pushtrain but the infrastructure in pushtrain/)

The C follows the same arrows: each room compiles its own C (``core/csrc`` the engine,
``cosim/csrc`` the co-simulation's step loop, ``fmu/src`` and ``fmu/controller_src`` the FMUs),
another room's C only through the engine's declared files (``core.native.engine_files``), the
Python face of a C function lives in the room of its C, and no C includes close a circle.

Every room may import ``pushtrain`` itself (errors, files, validation, limits).

Names have one home: every module says what it offers in ``__all__`` (its own names only), every
``from pushtrain... import name`` names the module where ``name`` is defined, and no module
imports or reads another module's ``_private`` name.
"""

import ast
import functools
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ROOMS = ("pushtrain", "core", "fmu", "facility", "planner", "cosim", "report", "mission",
         "ros", "studies", "cli")
ALLOWED = {
    "pushtrain": set(),
    "core": set(),
    "fmu": {"core"},
    "facility": {"core"},
    "planner": {"core", "facility"},
    "cosim": {"core", "fmu"},
    "report": {"core", "facility"},
    "mission": {"core", "fmu", "facility", "planner", "cosim"},
    "ros": {"core", "facility", "planner", "cosim", "mission"},
    "studies": {"core", "fmu", "facility", "planner", "cosim", "report", "mission"},
    "cli": {"core", "fmu", "facility", "planner", "cosim", "report", "mission", "ros",
            "studies"},
}
OWNERS = {"ompl": {"planner"}, "fmpy": {"cosim", "fmu"}, "dask": {"studies.sweep"},
          "distributed": {"studies.sweep"}, "ezdxf": {"facility.dxf"}, "rosbags": {"ros"}}


def _tree(path: Path) -> ast.Module:
    """The syntax tree of the file at ``path``: each text is parsed once for all the tests of
    this module (the trees are only read; a probe file rewritten under one name is parsed
    anew)."""
    return _parse(path.read_text())


@functools.cache
def _parse(text: str) -> ast.Module:
    return ast.parse(text)


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
    for node in ast.walk(_tree(path)):
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
        "def f():\n    from ..facility import free_space\n    import pushtrain.cosim.master\n"
    )
    try:
        found = _imports(probe)
    finally:
        probe.unlink()
    assert {"pushtrain.facility.free_space", "pushtrain.cosim.master"} <= found


@pytest.mark.parametrize("modules, forbidden", [
    ("pushtrain.planner, pushtrain.core.controller, pushtrain.core.reference, "
     "pushtrain.core.segment, pushtrain.core.sampled_reference", "fmpy"),
    ("pushtrain.cosim.master, pushtrain.core.governor, pushtrain.fmu", "ompl"),
    ("pushtrain.core.controller, pushtrain.core.pulling, pushtrain.core.analysis",
     "pushtrain.planner"),
    ("pushtrain.cli.main", "distributed"),
    ("pushtrain.cli.main", "rosbags"),
    ("pushtrain.facility.loading, pushtrain.facility.free_space, pushtrain.facility.dxf",
     "pushtrain.planner"),
])
def test_transitive_imports_stay_apart(modules, forbidden):
    code = f"import sys, {modules}; assert {forbidden!r} not in sys.modules, {forbidden!r}"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_no_bare_top_level_modules_leak_from_the_install():
    code = ("import importlib.util as u;"
            "leaks = [m for m in ('planner', 'cli', 'cosim', 'fmu', 'core', 'mission', 'studies',"
            " 'report', 'facility', 'ros') if u.find_spec(m) is not None];"
            "print(leaks)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd="/")
    assert done.stdout.strip() == "[]", done.stdout + done.stderr



# ------------------------------------------------------------------------ one home for each name
SCRIPT_FOLDERS = ("tests", "benchmarks", "examples", "docs")
"""Folders whose Python files import pushtrain as users do; their imports must name homes too."""


def _absolute_target(path: Path, node: ast.ImportFrom) -> str | None:
    """The module a ``from ... import`` names, made absolute (relative imports of the package)."""
    if not node.level:
        return node.module
    module = _module_name(path)
    package = module if _is_package(path) else module.rpartition(".")[0]
    base = package.split(".")
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _top_level_statements(tree: ast.Module):
    """The module's own statements, the bodies of top-level if/try blocks included."""
    todo = list(tree.body)
    while todo:
        node = todo.pop()
        yield node
        if isinstance(node, (ast.If, ast.Try)):
            todo += node.body + node.orelse + getattr(node, "finalbody", [])
            for handler in getattr(node, "handlers", []):
                todo += handler.body


def _defined_names(module: str) -> set[str]:
    """The names ``module`` binds itself (def, class, assignment), not the ones it imports."""
    names = set()
    for node in _top_level_statements(_tree(MODULES[module])):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names |= {n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)}
    return names


DEFINED = {module: _defined_names(module) for module in MODULES}


def _offered(module: str) -> list[str] | None:
    """The literal ``__all__`` of ``module``, or None when it has none."""
    for node in _top_level_statements(_tree(MODULES[module])):
        targets = node.targets if isinstance(node, ast.Assign) else (
            [node.target] if isinstance(node, ast.AnnAssign) else [])
        if any(isinstance(t, ast.Name) and t.id == "__all__" for t in targets):
            return ast.literal_eval(node.value)
    return None


def _lives_in(module: str, name: str) -> bool:
    return name in DEFINED[module] or f"{module}.{name}" in MODULES


def _user_files():
    yield from (path for _, path in _sources())
    for folder in SCRIPT_FOLDERS:
        yield from sorted((ROOT / folder).rglob("*.py"))


def _name_uses(path: Path):
    """Every (line, module, name) of a pushtrain module's name the file uses: ``from module import
    name`` and ``alias.name`` where ``alias`` is the module imported under a name of its own."""
    in_package = path.relative_to(ROOT).parts[0] in ROOMS
    tree = _tree(path)
    aliases = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            target = _absolute_target(path, node) if in_package else node.module
            if target not in MODULES:
                continue
            for alias in node.names:
                if f"{target}.{alias.name}" in MODULES:
                    aliases[alias.asname or alias.name] = f"{target}.{alias.name}"
                yield node.lineno, target, alias.name
        elif isinstance(node, ast.Import):
            aliases |= {a.asname: a.name for a in node.names if a.asname and a.name in MODULES}
    reads = [node for node in ast.walk(tree) if isinstance(node, ast.Attribute)
             and isinstance(node.value, ast.Name) and node.value.id in aliases]
    # a test may hang a name of its own on a module (monkeypatching) and read it back
    hung = {(node.value.id, node.attr) for node in reads if isinstance(node.ctx, ast.Store)}
    for node in reads:
        if isinstance(node.ctx, ast.Load) and (node.value.id, node.attr) not in hung:
            yield node.lineno, aliases[node.value.id], node.attr


def test_every_module_says_what_it_offers():
    missing = [module for module in MODULES if _offered(module) is None]
    assert not missing, f"modules without __all__: {missing}"


def test_every_module_offers_only_its_own_names():
    wrong = [f"{module}.__all__ offers {name!r}, which it does not define"
             for module in MODULES for name in _offered(module) or []
             if not _lives_in(module, name)]
    assert not wrong, "\n".join(wrong)


def test_every_import_names_the_home_of_the_name():
    """Package, tests, benchmarks and examples take each name from the module defining it."""
    wrong = [f"{path.relative_to(ROOT)}:{line}: {name!r} is not defined in {module}"
             for path in _user_files() for line, module, name in _name_uses(path)
             if not _lives_in(module, name) and not name.startswith("__")]
    assert not wrong, "\n".join(wrong)


def test_every_imported_pushtrain_module_exists():
    """No import names a module that moved or went away (package, tests, benchmarks, examples)."""
    wrong = []
    for path in _user_files():
        in_package = path.relative_to(ROOT).parts[0] in ROOMS
        for node in ast.walk(_tree(path)):
            if isinstance(node, ast.ImportFrom):
                targets = [_absolute_target(path, node) if in_package else node.module]
            elif isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            else:
                continue
            wrong += [f"{path.relative_to(ROOT)}:{node.lineno}: {target}" for target in targets
                      if target and target.split(".")[0] == "pushtrain" and target not in MODULES]
    assert not wrong, "modules that do not exist:\n" + "\n".join(wrong)


def test_the_home_rules_would_catch_a_re_export(tmp_path):
    probe = ROOT / "core" / "_probe_for_test.py"
    probe.write_text("import pushtrain.cosim.master as m\nfrom pushtrain.cosim.master import "
                     "np\nm.math\n__all__ = ['np']\n")
    try:
        MODULES["pushtrain.core._probe_for_test"] = probe
        DEFINED["pushtrain.core._probe_for_test"] = _defined_names("pushtrain.core._probe_for_test")
        uses = {(module, name) for _, module, name in _name_uses(probe)}
        offered = _offered("pushtrain.core._probe_for_test")
    finally:
        probe.unlink()
        del MODULES["pushtrain.core._probe_for_test"], DEFINED["pushtrain.core._probe_for_test"]
    assert uses == {("pushtrain.cosim.master", "np"), ("pushtrain.cosim.master", "math")}
    assert not any(_lives_in(module, name) for module, name in uses)
    assert offered == ["np"]


def _private_crossings(path: Path) -> list[str]:
    here = _module_name(path)
    return [f"{path.relative_to(ROOT)}:{line}: {module}.{name}"
            for line, module, name in _name_uses(path)
            if name.startswith("_") and not name.startswith("__") and module != here]


def test_no_private_name_crosses_a_module():
    """A module imports or reads no ``_name`` of another pushtrain module: a name used by two
    modules is public (documented, in ``__all__``) or stays home."""
    wrong = [crossing for _, path in _sources()
             for crossing in _private_crossings(path)]
    assert not wrong, "\n".join(wrong)


def test_the_privacy_rule_would_catch_a_crossing():
    probe = ROOT / "cli" / "_probe_for_test.py"
    probe.write_text("from pushtrain.cli import common\nfrom .common import _scenario\n"
                     "common._scenario\n")
    try:
        found = _private_crossings(probe)
    finally:
        probe.unlink()
    assert [f.split(": ")[1] for f in found] == ["pushtrain.cli.common._scenario"] * 2, found




# ---------------------------------------------------------------------------- the C rooms
C_FOLDERS = {"core": ["core/csrc"], "cosim": ["cosim/csrc"],
             "fmu": ["fmu/src", "fmu/controller_src"]}
C_DEFINITION_RE = __import__("re").compile(
    r"^(?:PT_API\s+)?[A-Za-z_][\w \*]*?\b(pt_\w+)\s*\([^;]*?\)\s*\{", __import__("re").M)


def _c_files():
    for room, folders in C_FOLDERS.items():
        for folder in folders:
            for path in sorted((ROOT / folder).glob("*.[ch]")):
                yield room, path


def test_fmu_imports_core_only_for_the_controller_fmu():
    """fmu -> core is one declared arrow: the controller FMU's builder takes the engine's C
    files (core.native.engine_files) and the path's Segment; nothing else of fmu imports
    core."""
    wrong = [f"{path.relative_to(ROOT)} imports {target}"
             for room, path, target in _internal_edges()
             if room == "fmu" and _room_of(target) == "core"
             and (path != ROOT / "fmu" / "controller.py"
                  or target not in ("pushtrain.core.native", "pushtrain.core.segment"))]
    assert not wrong, "\n".join(wrong)


def test_each_room_reads_only_its_own_c_files():
    """No module opens another room's C folder (``resources.files("pushtrain.<room>")``): the
    co-simulation's library and the controller FMU take the engine's files from
    core.native.engine_files, and the engine's library holds the engine's files only."""
    import re

    from pushtrain.core.native import ENGINE_FILES
    from pushtrain.cosim.step_loop import LOOP_FILES

    wrong = []
    for room, path in _sources():
        for package in re.findall(r'resources\.files\("pushtrain\.(\w+)"\)', path.read_text()):
            if package != room:
                wrong.append(f"{path.relative_to(ROOT)} reads pushtrain.{package}'s files")
    assert not wrong, "\n".join(wrong)
    engine = {name for names in ENGINE_FILES.values() for name in names}
    assert engine == {p.name for p in (ROOT / "core" / "csrc").glob("*.[ch]")}
    assert set(LOOP_FILES) == {p.name for p in (ROOT / "cosim" / "csrc").glob("*.[ch]")}


def test_the_python_face_of_each_c_function_is_in_its_room():
    """A product module calls a library's pt_* function only if that function is defined in its
    own room's C (the sensor model's C and Python are both core's; the step loop's both
    cosim's)."""
    import re

    home = {}
    for room, path in _c_files():
        for name in C_DEFINITION_RE.findall(path.read_text()):
            home.setdefault(name, room)
    wrong = []
    for room, path in _sources():
        for name in set(re.findall(r"lib\.(pt_\w+)", path.read_text())):
            if name in home and home[name] != room:
                wrong.append(f"{path.relative_to(ROOT)} calls {name} of {home[name]}'s C")
    assert len(home) > 30
    assert not wrong, "\n".join(wrong)


def test_c_includes_form_no_circle_and_follow_the_arrows():
    """#include "..." between the product's C files: no cycle; a room includes another room's
    headers only along an allowed arrow (cosim and the controller FMU include the engine's)."""
    import re

    where = {path.name: room for room, path in _c_files()}
    graph = {}
    wrong = []
    for room, path in _c_files():
        names = re.findall(r'^#include "([^"]+)"', path.read_text(), re.M)
        graph[path.name] = {n for n in names if n in where}
        for name in graph[path.name]:
            if where[name] != room and where[name] not in ALLOWED[room]:
                wrong.append(f"{path.relative_to(ROOT)} includes {name} of {where[name]}")
    assert not wrong, "\n".join(wrong)
    done, visiting = set(), []

    def visit(name):
        if name in visiting:
            raise AssertionError(f"include circle: {visiting[visiting.index(name):] + [name]}")
        if name in done:
            return
        visiting.append(name)
        for other in graph.get(name, ()):
            visit(other)
        visiting.pop()
        done.add(name)

    for name in graph:
        visit(name)


FUNCTION_DEFINITION_RE = __import__("re").compile(
    r"^(?:PT_INTERNAL\s+|PT_API\s+)?(?:static\s+)?(?:inline\s+)?[A-Za-z_][\w \*]*?\b(\w+)\s*"
    r"\([^;{]*\)\s*\{", __import__("re").M)


@pytest.mark.parametrize("files", [
    "core/csrc/*.c", "cosim/csrc/*.c", "fmu/controller_src/*.c",
    "fmu/src/model.c fmu/src/start.c fmu/src/variables.c fmu/src/chain.c fmu/src/forces.c "
    "fmu/src/slip.c fmu/src/slip_solver.c fmu/src/instance.c fmu/src/fmi2.c",
])
def test_c_files_call_one_another_without_a_circle(files):
    """Within one build's own C, file A calling a function defined in file B and B calling one
    of A's (directly or through others) is a circle: the plant's model.c <-> slip.c <->
    slip_solver.c and model.c <-> variables.c were."""
    import re

    paths = [p for pattern in files.split() for p in sorted(ROOT.glob(pattern))]
    home = {}
    for path in paths:
        for name in FUNCTION_DEFINITION_RE.findall(path.read_text()):
            home.setdefault(name, path.name)
    graph = {path.name: set() for path in paths}
    for path in paths:
        text = path.read_text()
        for name, where in home.items():
            if where != path.name and re.search(rf"\b{name}\s*\(", text):
                graph[path.name].add(where)
    done, visiting = set(), []

    def visit(name):
        if name in visiting:
            raise AssertionError(f"call circle: {visiting[visiting.index(name):] + [name]}")
        if name not in done:
            visiting.append(name)
            for other in sorted(graph[name]):
                visit(other)
            visiting.pop()
            done.add(name)

    for name in graph:
        visit(name)
    assert len(paths) >= 1


TEST_ROOMS = {*ROOMS, "base", "benchmarks"} - {"pushtrain"}
"""Folders of tests/: one a room (``base`` for ``pushtrain/`` itself, ``benchmarks`` for the
benchmark scripts' own checks)."""
CROSS_ROOM_TESTS = {"test_examples.py", "test_imports.py", "test_one_definition.py"}
"""The test modules of the whole product, which stay at the top of tests/."""


def test_tests_are_laid_out_like_the_product():
    """tests/<room>/test_<module>.py: every test module in the folder of the room it tests (or
    one of the few cross-room modules at the top), none named after an issue."""
    tests = ROOT / "tests"
    wrong = []
    for path in sorted(tests.rglob("test_*.py")):
        where = path.relative_to(tests)
        if len(where.parts) == 1:
            ok = where.name in CROSS_ROOM_TESTS
        else:
            ok = len(where.parts) == 2 and where.parts[0] in TEST_ROOMS
        if not ok or any(word in path.stem for word in ("planted", "issue")):
            wrong.append(str(where))
    assert not wrong, "test modules outside tests/<room>/ or named after an issue: " + \
        ", ".join(wrong)

