"""The FMU cache: ``PUSHTRAIN_CACHE`` naming a file is bad input naming it (exit 2, no
traceback); a cached FMU that is damaged (cut short by an interrupted copy or a full disk) is
found, rebuilt, and the run says so."""

from __future__ import annotations

import zipfile
from pathlib import Path

import pytest
from conftest import EXAMPLES
from conftest import invoke_cli as _invoke
from conftest import short_run as _short


def test_pushtrain_cache_that_is_a_file_exits_2_naming_it(tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    cache.write_text("not a folder")
    monkeypatch.setenv("PUSHTRAIN_CACHE", str(cache))
    result = _invoke(["run", _short(tmp_path), "--no-plots", "--out", tmp_path / "o"])
    assert result.exit_code == 2, result.output
    assert "PUSHTRAIN_CACHE" in result.output and str(cache) in result.output
    assert "allowed" in result.output
    assert cache.read_text() == "not a folder"
    built = _invoke(["build-fmu", "-n", "1", "-o", tmp_path / "t.fmu"])
    assert built.exit_code == 2 and "PUSHTRAIN_CACHE" in built.output, built.output


@pytest.mark.slow
@pytest.mark.parametrize("damage", ["truncated", "empty", "garbage"])
def test_a_damaged_fmu_in_the_cache_is_rebuilt_and_said_so(tmp_path, monkeypatch, built_fmu,
                                                            damage):
    """An FMU cut short by an interrupted copy or a full disk (or any other damage) is found
    when the cache is asked, rebuilt, and the run goes on."""
    from pushtrain.fmu.build import cached_path

    good = Path(built_fmu(1)).read_bytes()
    monkeypatch.setenv("PUSHTRAIN_CACHE", str(tmp_path / "cache"))
    cached = cached_path(1)
    cached.parent.mkdir(parents=True)
    cached.write_bytes({"truncated": good[:len(good) // 2], "empty": b"",
                        "garbage": good[:100] + bytes(len(good) - 100)}[damage])
    result = _invoke(["run", _short(tmp_path, n=1), "--no-plots", "--out", tmp_path / "o"])
    assert result.exit_code == 1, result.output  # the short horizon misses the goal
    assert f"the cached FMU {cached} is damaged" in result.output, result.output
    assert "rebuilding the FMU (FMI 2.0; the cached copy is damaged)" in result.output
    with zipfile.ZipFile(cached) as rebuilt:
        assert rebuilt.testzip() is None and "modelDescription.xml" in rebuilt.namelist()
    again = _invoke(["run", _short(tmp_path, n=1), "--no-plots", "--out", tmp_path / "o"])
    assert again.exit_code == 1 and "building the FMU" not in again.output, again.output


@pytest.mark.slow
def test_a_damaged_controller_fmu_in_the_cache_is_rebuilt(tmp_path, monkeypatch):
    """The controller FMU of export-ssp is cached the same way, and checked the same way."""
    monkeypatch.setenv("PUSHTRAIN_CACHE", str(tmp_path / "cache"))
    export = ["export-ssp", str(EXAMPLES / "circle.toml"), "-o", tmp_path / "c.ssp"]
    assert _invoke(export).exit_code == 0
    [cached] = (tmp_path / "cache" / "fmu").glob("BackwardController-*.fmu")
    cached.write_bytes(cached.read_bytes()[:1000])
    result = _invoke(export)
    assert result.exit_code == 0, result.output
    assert f"the cached FMU {cached} is damaged" in result.output, result.output
    with zipfile.ZipFile(cached) as rebuilt:
        assert rebuilt.testzip() is None
