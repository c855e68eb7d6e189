"""Run folders held by the run that writes them (a second run into one is refused while the
first writes), and result files on a full disk (named, no partial file left)."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest
from conftest import invoke_cli as _invoke
from conftest import short_run as _short

from pushtrain.errors import InputError
from pushtrain.files import (
    RUN_MARKER,
    WriteError,
    atomic_write,
    claim_run_folder,
    fresh_run_folder,
)


# ----------------------------------------------------------------------- run folders in use
def test_a_run_folder_is_claimed_by_one_run_at_a_time(tmp_path):
    out = tmp_path / "run"
    with claim_run_folder(out) as claimed:
        assert claimed == out and (out / RUN_MARKER).is_file()
        (out / "summary.json").write_text("first")
        with pytest.raises(InputError, match="in use by another run"):
            with claim_run_folder(out):
                pass
        with pytest.raises(InputError, match="in use by another run"):
            fresh_run_folder(out)
        assert (out / "summary.json").read_text() == "first"
    with claim_run_folder(out):  # free again: the previous run is replaced
        assert sorted(p.name for p in out.iterdir()) == [RUN_MARKER]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_a_new_folder_claimed_by_two_at_once_goes_to_one(tmp_path):
    """Both find the folder missing (or empty); the one that locks its marker first writes."""
    out = tmp_path / "new"
    with claim_run_folder(out):
        with pytest.raises(InputError, match="in use by another run"):
            with claim_run_folder(out):
                pass
    empty = tmp_path / "empty"
    empty.mkdir()
    with claim_run_folder(empty):
        with pytest.raises(InputError, match=f"{empty}"):
            fresh_run_folder(empty)


def test_a_forked_child_does_not_keep_the_run_folder_claimed(tmp_path):
    """The plot processes are forked children: the claim ends with the run, not with them."""
    import multiprocessing

    out = tmp_path / "run"
    context = multiprocessing.get_context("fork")
    parent, child = context.Pipe()
    with claim_run_folder(out):
        process = context.Process(target=_wait_on, args=(child,))
        process.start()
        assert parent.recv() == "started"  # past its start (the fork's hooks)
    try:
        with claim_run_folder(out):
            pass
    finally:
        parent.send("end")
        process.join()


def _wait_on(conn):
    conn.send("started")
    conn.recv()


# ---------------------------------------------------------------------------------- full disk
def test_a_full_disk_is_named_with_the_file_and_its_folder(tmp_path):
    target = tmp_path / "results.npz"

    def full(partial):
        partial.write_bytes(b"PK half")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with pytest.raises(WriteError) as info:
        atomic_write(target, full)
    assert str(info.value) == f"disk full while writing results.npz in {tmp_path}"
    assert isinstance(info.value, OSError) and info.value.errno == errno.ENOSPC
    assert list(tmp_path.iterdir()) == []


def test_a_full_disk_while_saving_results_is_exit_1_naming_the_file(tmp_path, monkeypatch):
    from pushtrain.cosim import result as results

    def full(partial, data):
        Path(partial).write_bytes(b"PK half")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(results, "write_npz", full)
    out = tmp_path / "out"
    result = _invoke(["run", _short(tmp_path), "--no-plots", "--out", out])
    assert result.exit_code == 1, result.output
    assert f"disk full while writing results.npz in {out}" in result.output
    assert sorted(p.name for p in out.iterdir()) == [RUN_MARKER, "run.log", "scenario.json",
                                                     "summary.json"]


def test_writing_to_dev_full_is_a_disk_full_error():
    """The kernel's own ENOSPC (``/dev/full``) reads as the disk full it is."""
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full")
    with pytest.raises(OSError) as info:
        with open("/dev/full", "wb") as f:
            f.write(b"x")
    error = WriteError(Path("/data/run/results.npz"), info.value)
    assert str(error) == "disk full while writing results.npz in /data/run"


@pytest.mark.parametrize("name, stem", [("..hidden", "hidden"), ("a b/c", "a_b_c"),
                                        (".", "run"), ("_x_.", "x")])
def test_the_default_folder_is_a_visible_plain_name(tmp_path, monkeypatch, name, stem):
    """runs/<name>-<timestamp>: the name reduced to letters, digits, '.', '_', '-', never
    starting with a dot (a hidden folder) and never empty."""
    import re

    from pushtrain.cli.rundir import default_folder

    monkeypatch.chdir(tmp_path)
    folder = default_folder(name)
    assert folder.parent == Path("runs")
    assert re.fullmatch(re.escape(stem) + r"-\d{8}-\d{6}", folder.name), folder.name
