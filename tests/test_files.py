"""Atomic writes: the target changes only when the whole write succeeded."""

import pytest

from pushtrain.files import atomic_write, atomic_write_bytes, atomic_write_text


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
