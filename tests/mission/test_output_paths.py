"""Output paths the CLI writes to: an empty ``--out`` is refused (it fell back to the default
folder, or wrote nothing, or wrote into the current folder), and ``export-ssp -o`` replaces an
earlier package only (not a file of another kind, a link, a FIFO or a device). Bad input is
exit 2 naming the option, the value and what is allowed; never a traceback."""

from __future__ import annotations

import os
import stat
import zipfile

import pytest
from conftest import EXAMPLES
from conftest import invoke_cli as _invoke
from conftest import short_run as _short

from pushtrain.errors import InputError


# ------------------------------------------------------------------------------- empty paths
@pytest.mark.parametrize("args, option", [
    (["run", "{short}", "--no-plots", "--out", ""], "--out"),
    (["plan-and-run", "{short}", "--no-plots", "--out", ""], "--out"),
    (["slip-study", "--trailers", "1", "--alphas", "5", "--out", ""], "--out"),
    (["plan", str(EXAMPLES / "l_corridor.toml"), "--out", ""], "--out"),
    (["plan", str(EXAMPLES / "l_corridor.toml"), "--plot", ""], "--plot"),
    (["build-fmu", "-n", "1", "-o", ""], "--out"),
    (["export-ssp", str(EXAMPLES / "circle.toml"), "-o", ""], "-o"),
    (["sweep", str(EXAMPLES / "joint_bias_5deg.toml"), "--spec",
      str(EXAMPLES / "sweeps" / "joint_bias.toml"), "--workers", "0", "--out", ""], "--out"),
])
def test_an_empty_output_path_is_refused(tmp_path, monkeypatch, args, option):
    """``--out ""`` is not "no --out": it used to fall back to runs/<name>-<timestamp> (or to
    ./TrailerTrain.fmu, or to nothing written at all)."""
    short = str(_short(tmp_path))
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    result = _invoke([a.replace("{short}", short) for a in args])
    assert result.exit_code == 2, result.output
    assert f"{option} ''" in result.output and "empty" in result.output, result.output
    assert "allowed" in result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == before


# ------------------------------------------------------------------------------ the SSP target
def _export(target):
    return _invoke(["export-ssp", str(EXAMPLES / "circle.toml"), "-o", target])


def _refused(result, target, what):
    assert result.exit_code == 2, result.output
    assert f"-o {target}" in result.output and what in result.output, result.output
    assert "allowed: a new path or an earlier .ssp package" in result.output


def test_export_ssp_refuses_to_replace_a_file_of_another_kind(tmp_path):
    notes = tmp_path / "notes.txt"
    notes.write_text("precious")
    _refused(_export(notes), notes, "not an SSP package")
    assert notes.read_text() == "precious"
    other_zip = tmp_path / "other.zip"
    with zipfile.ZipFile(other_zip, "w") as zf:
        zf.writestr("data.txt", "mine")
    before = other_zip.read_bytes()
    _refused(_export(other_zip), other_zip, "SystemStructure.ssd")
    assert other_zip.read_bytes() == before


def test_export_ssp_refuses_fifos_links_and_devices(tmp_path):
    fifo = tmp_path / "pipe.ssp"
    os.mkfifo(fifo)
    _refused(_export(fifo), fifo, "not a regular file")
    assert stat.S_ISFIFO(fifo.lstat().st_mode)
    first = tmp_path / "first.ssp"
    assert _export(first).exit_code == 0
    link = tmp_path / "link.ssp"
    link.symlink_to(first)
    _refused(_export(link), link, "symbolic link")
    assert link.is_symlink()
    if os.geteuid() == 0:  # as root, -o /dev/full replaced the device with a regular file
        device = tmp_path / "null"
        os.mknod(device, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
        _refused(_export(device), device, "not a regular file")
        assert stat.S_ISCHR(device.lstat().st_mode)


def test_export_ssp_replaces_an_earlier_package(tmp_path):
    target = tmp_path / "mission.ssp"
    assert _export(target).exit_code == 0
    first_inode = target.stat().st_ino
    again = _export(target)
    assert again.exit_code == 0, again.output
    assert target.stat().st_ino != first_inode, "replaced by a rename, not rewritten in place"
    with zipfile.ZipFile(target) as zf:
        assert "SystemStructure.ssd" in zf.namelist()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mission.ssp"]


def test_the_library_export_checks_its_target_too(tmp_path):
    from pushtrain.mission.ssp import check_ssp_target

    notes = tmp_path / "notes.txt"
    notes.write_text("precious")
    with pytest.raises(InputError, match="not an SSP package"):
        check_ssp_target(notes)
    check_ssp_target(tmp_path / "new.ssp")
