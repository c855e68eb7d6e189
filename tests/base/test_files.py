"""Atomic writes (the target changes only when the whole write succeeded) and run folders
(one run per folder, replaced whole)."""

import pytest

from pushtrain.errors import InputError
from pushtrain.files import (
    RUN_MARKER,
    atomic_write,
    atomic_write_bytes,
    atomic_write_text,
    fresh_run_folder,
    is_run_folder,
)


def test_a_failed_write_leaves_the_target_and_no_partial_file(tmp_path):
    target = tmp_path / "summary.json"
    atomic_write_text(target, "old")

    def fail(partial):
        partial.write_text("half")
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        atomic_write(target, fail)
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["summary.json"]


def test_partial_names_and_suffix(tmp_path):
    seen = []

    def record(partial):
        seen.append(partial.name)
        partial.write_bytes(b"x")

    atomic_write(tmp_path / "map.png", record, keep_suffix=True)
    atomic_write(tmp_path / "results.csv", record)
    assert seen[0].startswith(".map.") and seen[0].endswith(".part.png")
    assert seen[1].startswith(".results.csv.") and seen[1].endswith(".part")
    assert atomic_write_bytes(tmp_path / "a.bin", b"\x00\x01").read_bytes() == b"\x00\x01"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.bin", "map.png", "results.csv"]


# ------------------------------------------------------------------------------- run folders
def _names(folder):
    return sorted(p.name for p in folder.iterdir())


def test_a_new_run_folder_is_created_with_its_parents_and_marked_first(tmp_path):
    out = fresh_run_folder(tmp_path / "a" / "b")
    assert _names(out) == [RUN_MARKER] and is_run_folder(out)
    empty = tmp_path / "empty"
    empty.mkdir()
    assert _names(fresh_run_folder(empty)) == [RUN_MARKER]


def test_a_previous_run_is_replaced_whole_and_nothing_is_left_beside_it(tmp_path):
    out = fresh_run_folder(tmp_path / "run")
    (out / "summary.json").write_text("old")
    (out / "plots").mkdir()
    (out / "plots" / "map.png").write_bytes(b"old")
    fresh_run_folder(out)
    assert _names(out) == [RUN_MARKER]
    assert _names(tmp_path) == ["run"], "the old run moved aside must be deleted"


@pytest.mark.parametrize("setup, needle", [
    (lambda d: (d / "mine.txt").write_text("keep"), "not a pushtrain run folder"),
    (lambda d: (d / ".hidden").write_text("keep"), "not a pushtrain run folder"),
])
def test_a_folder_of_other_files_is_refused_and_left_alone(tmp_path, setup, needle):
    folder = tmp_path / "theirs"
    folder.mkdir()
    setup(folder)
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    with pytest.raises(InputError, match=needle):
        fresh_run_folder(folder)
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before


def test_paths_that_cannot_be_folders_are_input_errors(tmp_path):
    (tmp_path / "some_file").write_text("x")
    with pytest.raises(InputError, match="is a file"):
        fresh_run_folder(tmp_path / "some_file")
    with pytest.raises(InputError, match="some_file' is a file"):
        fresh_run_folder(tmp_path / "some_file" / "sub")
    with pytest.raises(InputError, match="No such file or directory"):
        fresh_run_folder("/proc/pushtrain-test/x")
    assert (tmp_path / "some_file").read_text() == "x"


@pytest.mark.parametrize("parts", [["N" * 300], ["d" * 200] * 25])
def test_a_name_or_path_too_long_is_an_input_error_quoted_short(tmp_path, parts):
    with pytest.raises(InputError, match="File name too long") as err:
        fresh_run_folder(tmp_path.joinpath(*parts))
    assert len(str(err.value)) < 600


def test_a_run_folder_holding_the_current_folder_is_not_replaced(tmp_path, monkeypatch):
    out = fresh_run_folder(tmp_path / "run")
    (out / "summary.json").write_text("old")
    (out / "inside").mkdir()
    monkeypatch.chdir(out / "inside")
    with pytest.raises(InputError, match="current folder"):
        fresh_run_folder(out)
    assert (out / "summary.json").read_text() == "old"

