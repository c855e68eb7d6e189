"""Property-based tests of the scenario and CLI layer: random and mutated scenario files.

The bundled examples' TOML is mutated (keys deleted or added, values replaced by other types,
huge, negative or non-finite numbers, numbers scaled, bytes that are not UTF-8, files cut
short) and fed to ``pushtrain validate`` and ``pushtrain plan-and-run --no-plots`` in-process.
Every call must end with exit 0, 1 or 2 and no traceback, and the output folder, shared by all
runs, must never hold files of two runs. The examples' horizon and planning time are capped so
that a run takes about a second; plan-and-run is skipped for mutants that would take long.
"""

from __future__ import annotations

import copy
import json
import math
import tomllib
from pathlib import Path

import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from pushtrain.cli.main import cli
from pushtrain.files import RUN_MARKER

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SECTIONS = ("mission", "train", "robot", "map", "start", "goal", "planner", "reference",
            "rotation", "controller", "sensors", "events", "fmu", "sim")


# --------------------------------------------------------------------------- TOML writing
def _value(v) -> str:
    """One TOML value (tables inline)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        return repr(v) if math.isfinite(v) else ("inf" if v > 0 else "-inf")
    if isinstance(v, str):
        return json.dumps(v)  # JSON string escapes are valid TOML basic-string escapes
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def dumps(doc: dict) -> str:
    """A TOML document with every top-level key on one line."""
    return "".join(f"{json.dumps(k)} = {_value(v)}\n" for k, v in doc.items())


def _capped(doc: dict) -> dict:
    """The example with a 1 s horizon and 0.3 s of planning."""
    doc = copy.deepcopy(doc)
    doc.setdefault("sim", {})["horizon"] = 1.0
    doc.setdefault("planner", {}).update(time_budget=0.3, anytime_time=0.2)
    return doc


BASES = {p.stem: _capped(tomllib.loads(p.read_text())) for p in sorted(EXAMPLES.glob("*.toml"))}


def test_the_writer_round_trips_every_example():
    for name, doc in BASES.items():
        assert tomllib.loads(dumps(doc)) == doc, name


# ------------------------------------------------------------------------------ mutations
HUGE = [0, -1, 10**30, -(10**30), 2**63, float("nan"), float("inf"), float("-inf"), 1e308,
        -1e308, 5e-324, -0.0, 1e-12]
scalars = st.one_of(
    st.sampled_from(HUGE),
    st.integers(-(10**6), 10**6),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=10),
    st.booleans(),
)
values = st.one_of(scalars, st.lists(scalars, max_size=4), st.builds(dict),
                   st.dictionaries(st.text(min_size=1, max_size=6), scalars, max_size=3))
FACTORS = [-1.0, 0.0, 1e-3, 0.5, 2.0, 10.0, 1e3, 1e9]
UNKNOWN = "zz_"  # prefix of keys no scenario has


def _places(node, prefix=()):
    """Every (path) to a value in a document: keys of tables, indices of arrays."""
    items = node.items() if isinstance(node, dict) else enumerate(node)
    for key, child in items:
        yield prefix + (key,)
        if isinstance(child, (dict, list)):
            yield from _places(child, prefix + (key,))


def _tables(node, prefix=()):
    if isinstance(node, dict):
        yield prefix
    if isinstance(node, (dict, list)):
        for key, child in node.items() if isinstance(node, dict) else enumerate(node):
            yield from _tables(child, prefix + (key,))


def _at(doc, path):
    for key in path:
        doc = doc[key]
    return doc


WORDS = ["plan", "scripted", "rotation", "line", "arc", "left", "right", "push", "pull", "slide",
         "bias", "rrtconnect", "restarts", "rrtstar", "robot", "last_trailer", ""]
near = st.one_of(st.floats(-50, 50), st.integers(-3, 10), st.sampled_from(WORDS))
WILD_OPS = ["set", "scale", "retype", "delete", "add"]
GENTLE_OPS = ["scale", "scale", "near", "delete"]  # mostly values of the right type


def _mutate_once(data, doc: dict, gentle: bool) -> None:
    places = list(_places(doc))
    ops = (GENTLE_OPS if gentle else WILD_OPS) if places else ["add"]
    op = data.draw(st.sampled_from(ops))
    if op == "add":
        table = data.draw(st.sampled_from(list(_tables(doc))))
        key = data.draw(st.one_of(st.sampled_from(SECTIONS),
                                  st.text(max_size=6).map(lambda t: UNKNOWN + t)))
        _at(doc, table)[key] = data.draw(values)
        return
    path = data.draw(st.sampled_from(places))
    parent, key = _at(doc, path[:-1]), path[-1]
    old = parent[key]
    if op == "delete":
        del parent[key]
    elif op in ("set", "near"):
        parent[key] = data.draw(values if op == "set" else near)
    elif op == "scale" and isinstance(old, (int, float)) and not isinstance(old, bool):
        new = old * data.draw(st.sampled_from(FACTORS))
        parent[key] = int(new) if isinstance(old, int) and math.isfinite(new) else new
    else:  # retype: a number as text, text as a number, a list as its first element, ...
        parent[key] = (str(old) if isinstance(old, (int, float)) else
                       old[0] if isinstance(old, list) and old else
                       [old] if not isinstance(old, list) else 1.5)


def _bytes_mutation(data, raw: bytes) -> tuple[str, bytes]:
    kind = data.draw(st.sampled_from(["none", "none", "none", "not_utf8", "cut"]))
    if kind == "none" or not raw:
        return "none", raw
    at = data.draw(st.integers(0, len(raw) - 1))
    if kind == "cut":
        return kind, raw[:at]
    bad = data.draw(st.sampled_from([b"\xff", b"\xc3", b"\x80", b"\xe9t\xe9"]))
    return kind, raw[:at] + bad + raw[at:]


def _has_unknown_key(node) -> bool:
    if isinstance(node, dict):
        return any(str(k).startswith(UNKNOWN) or _has_unknown_key(v) for k, v in node.items())
    return isinstance(node, list) and any(_has_unknown_key(v) for v in node)


@st.composite
def scenario_files(draw, gentle: bool = False):
    """(name of the base, bytes of the file): a mutated example or a random document; with
    ``gentle``, mostly values of the right type (more mutants pass validation and run)."""
    kind = draw(st.sampled_from(sorted(BASES) + ([] if gentle else ["random"])))
    if kind == "random":
        doc = draw(st.dictionaries(st.sampled_from(SECTIONS + ("name", "seed")),
                                   st.dictionaries(st.text(min_size=1, max_size=8), values,
                                                   max_size=4) | scalars, max_size=5))
    else:
        doc = copy.deepcopy(BASES[kind])
        data = draw(st.data())
        for _ in range(draw(st.integers(0 if gentle else 1, 3))):
            _mutate_once(data, doc, gentle and draw(st.integers(0, 3)) > 0)
    raw = dumps(doc).encode("utf-8", "surrogatepass")
    flags = {"unknown_key"} if _has_unknown_key(doc) else set()
    if not gentle:
        damage, raw = _bytes_mutation(draw(st.data()), raw)
        flags.add(damage)
    return kind, raw, flags


# ------------------------------------------------------------------------------- checks
def _invoke(args):
    result = CliRunner().invoke(cli, args)
    assert result.exception is None or isinstance(result.exception, SystemExit), (
        args, result.output, result.exception)
    assert "Traceback" not in result.output, result.output
    assert result.exit_code in (0, 1, 2), (args, result.exit_code, result.output)
    return result


def _snapshot(folder: Path) -> set:
    if not folder.exists():
        return set()
    return {(str(p.relative_to(folder)), p.stat().st_ino, p.stat().st_mtime_ns)
            for p in folder.rglob("*") if p.is_file()}


def _quick(path: Path) -> bool:
    """Whether plan-and-run on this (valid) file takes about a second."""
    from pushtrain.mission.scenario import load_scenario

    sc = load_scenario(path)
    horizon = sc.sim.horizon
    return (sc.train.n <= 3 and horizon is not None and horizon <= 2.0
            and horizon / sc.sim.step <= 2000 and sc.sim.step / sc.fmu.max_substep <= 100
            and sc.planner.time_budget <= 0.5 and sc.planner.anytime_time <= 0.5)


def _check_one_run(out: Path, before: set, code: int) -> None:
    """The folder is untouched, or it holds the files of the new run only, which say so."""
    after = _snapshot(out)
    assert not list(out.parent.glob(".*replaced*")), "a replaced run was left beside the folder"
    if after == before:
        assert code == 2, "a run that did not touch its folder must have been refused"
        return
    mixed = after & before
    assert not mixed, f"files of the previous run left beside the new one: {sorted(mixed)}"
    names = {name for name, _, _ in after}
    assert {RUN_MARKER, "run.log", "scenario.json", "summary.json"} <= names, names
    assert not any(name.endswith(".part") or ".part." in name for name in names), names
    summary = json.loads((out / "summary.json").read_text())
    scenario = json.loads((out / "scenario.json").read_text())
    assert summary["scenario"] == scenario["name"]
    assert (summary["status"] in ("goal_reached", "completed")) == (code == 0), summary
    assert ("results.npz" in names) == (summary["status"] not in
                                        ("invalid", "planning_failed", "failed")), names


def _finite_numbers(node) -> bool:
    if isinstance(node, float):
        return math.isfinite(node)
    if isinstance(node, dict):
        node = list(node.values())
    return not isinstance(node, list) or all(_finite_numbers(v) for v in node)


@settings(max_examples=300, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(case=scenario_files())
def test_validate_never_crashes(tmp_path_factory, case):
    """Exit 0 or 2, never a traceback; files that are not UTF-8 or carry an unknown key are
    refused; whatever is accepted holds finite numbers only."""
    from pushtrain.mission.scenario import load_scenario

    base, raw, flags = case
    path = tmp_path_factory.mktemp("validate") / f"{base}.toml"
    path.write_bytes(raw)
    result = _invoke(["validate", str(path)])
    event(f"validate exit {result.exit_code}")
    assert result.exit_code in (0, 2), result.output
    if result.exit_code == 2:
        assert "Error:" in result.output
    if "not_utf8" in flags:
        assert result.exit_code == 2 and "UTF-8" in result.output, result.output
    if "unknown_key" in flags:
        assert result.exit_code == 2, result.output
    if result.exit_code == 0:
        assert _finite_numbers(load_scenario(path).model_dump())


@pytest.mark.slow
@settings(max_examples=100, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(case=scenario_files(gentle=True))
def test_plan_and_run_never_crashes_nor_mixes_runs(tmp_path_factory, case):
    base, raw, _ = case
    folder = tmp_path_factory.getbasetemp() / "fuzz_runs"
    folder.mkdir(exist_ok=True)
    path = folder / f"{base}.toml"
    path.write_bytes(raw)
    if _invoke(["validate", str(path)]).exit_code != 0:
        event("invalid")
        return
    if not _quick(path):
        event("valid, not run (slow)")
        return
    out = folder / "out"
    before = _snapshot(out)
    result = _invoke(["plan-and-run", str(path), "--no-plots", "--out", str(out)])
    event(f"plan-and-run exit {result.exit_code}")
    _check_one_run(out, before, result.exit_code)
