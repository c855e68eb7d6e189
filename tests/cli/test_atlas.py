"""``pushtrain atlas``'s options and facility names a careless or hostile user gives: each is
exit 2 naming the option or field, the value and what is allowed, checked before any work; or
it runs as documented. Never a traceback, a huge allocation or an empty atlas."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from pushtrain.cli.main import cli

ROOT = Path(__file__).resolve().parents[2]
FACILITY = ROOT / "examples" / "atlas" / "facility.toml"
QUICK = ["--trailers", "1", "--stations", "hall,store"]  # a dead end: answered in seconds


def _invoke(args):
    return CliRunner().invoke(cli, ["atlas", *map(str, args)])


def _refused(done, *needles):
    assert done.exit_code == 2, done.output
    assert done.exception is None or isinstance(done.exception, SystemExit), done.exception
    for needle in needles:
        assert needle in done.output, (needle, done.output)


def _facility(tmp_path, edit) -> Path:
    path = tmp_path / "facility.toml"
    path.write_text(edit(FACILITY.read_text()))
    return path


# ----------------------------------------------------------------------------- names (item 1)
def test_a_station_name_ending_in_a_newline_is_refused(tmp_path):
    bad = _facility(tmp_path, lambda t: t.replace('name = "hall"', 'name = "hall\\n"'))
    done = _invoke([bad, *QUICK, "--out", tmp_path / "out", "--serial"])
    _refused(done, "stations[2].name", "'hall\\n'", "letters, digits")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("name", ["{{DATA}}", "a\nb", "../up", "x" * 61, ""])
def test_a_facility_name_that_is_not_a_plain_name_is_refused(tmp_path, name):
    text = FACILITY.read_text()
    first = re.search(r"^name = .*$", text, flags=re.M)
    assert first, "the example names its facility"
    bad = _facility(tmp_path, lambda t: t.replace(first.group(0), f"name = {json.dumps(name)}",
                                                  1))
    done = _invoke([bad, *QUICK, "--out", tmp_path / "out", "--serial"])
    _refused(done, "name", "1-60 letters")


def test_template_markers_in_a_page_title_are_shown_not_substituted(tmp_path):
    from pushtrain.report.html import write_table_page

    page = write_table_page(tmp_path / "r.html", "{{DATA}} {{JS}} {{CSS}} <b>", {"a": 1},
                            ["x"], [[1]]).read_text()
    title = re.search(r"<title>(.*?)</title>", page, flags=re.S).group(1)
    assert title == "{{DATA}} {{JS}} {{CSS}} &lt;b>", title


# ------------------------------------------------------------------------- --trailers (item 2)
@pytest.mark.parametrize("value", ["1-99999999999", "1_0", "1-1_0", " 1 - 3", "+2", "3-1",
                                   "0", "1,,3", "1-51", "١"])
def test_bad_trailer_counts_are_refused_before_anything_is_expanded(tmp_path, value):
    done = _invoke([FACILITY, "--trailers", value, "--out", tmp_path / "out", "--serial"])
    _refused(done, "--trailers", "within 1..")
    assert not (tmp_path / "out").exists()


def test_trailer_counts_are_read_as_written():
    from pushtrain.studies.atlas import parse_trailers

    assert parse_trailers("1-5") == (1, 2, 3, 4, 5)
    assert parse_trailers("3") == (3,)
    assert parse_trailers("5,1,3,3") == (1, 3, 5)
    assert parse_trailers("50") == (50,)


def test_a_facility_train_n_is_refused_not_replaced(tmp_path):
    assert "[train]" not in FACILITY.read_text()
    bad = _facility(tmp_path, lambda t: t + "\n[train]\nn = 3\n")
    done = _invoke([bad, *QUICK, "--out", tmp_path / "out", "--serial"])
    _refused(done, "train.n", "3", "--trailers")


# -------------------------------------------------------------------------- --workers (item 3)
def test_workers_0_runs_serially_as_for_sweep(tmp_path):
    out = tmp_path / "out"
    done = _invoke([FACILITY, *QUICK, "--out", out, "--workers", "0"])
    assert done.exit_code == 0, done.output
    assert "Dask" not in done.output
    doc = json.loads((out / "atlas.json").read_text())
    assert {(p["from"], p["to"]) for p in doc["pairs"]} == {("hall", "store"), ("store", "hall")}


def test_more_workers_than_cores_are_capped_with_a_message(capsys):
    from pushtrain.cli.common import local_workers, usable_cores

    cores = usable_cores()
    assert local_workers(cores, None) == cores
    assert local_workers(256, None) == min(256, cores)
    if cores < 256:
        assert f"--workers 256: more than the {cores} core(s)" in capsys.readouterr().err
    assert local_workers(0, None) == 0 and local_workers(None, None) is None


def test_workers_with_a_scheduler_is_refused(tmp_path):
    done = _invoke([FACILITY, *QUICK, "--out", tmp_path / "out", "--workers", "2",
                    "--scheduler", "tcp://127.0.0.1:1"])
    _refused(done, "--workers 2", "--scheduler")


# ------------------------------------------------------------------------- --stations (item 5)
def test_a_station_given_twice_is_refused(tmp_path):
    done = _invoke([FACILITY, "--trailers", "1", "--stations", "hall,hall", "--out",
                    tmp_path / "out", "--serial"])
    _refused(done, "--stations", "each once", "hall given twice")
    assert not (tmp_path / "out").exists()


# ----------------------------------------------------------------------- output paths (item 6)
@pytest.mark.parametrize("out", ["/proc/pushtrain-atlas/x", "N" * 300,
                                 "/".join(["d" * 200] * 25)])
def test_an_out_folder_that_cannot_be_written_is_exit_2_before_any_work(tmp_path, monkeypatch,
                                                                        out):
    monkeypatch.chdir(tmp_path)
    done = _invoke([FACILITY, *QUICK, "--out", out, "--serial"])
    _refused(done, "--out", "cannot be written", "allowed")
    assert len(done.output) < 2000


@pytest.mark.slow
def test_the_atlas_says_that_it_starts_dask_and_times_the_pairs_after_it(tmp_path):
    """Starting the LocalCluster takes seconds to tens of seconds: it is announced, and the
    time estimates count from when the pairs started, not from before the cluster."""
    import subprocess
    import sys

    exe = Path(sys.executable).with_name("pushtrain")
    proc = subprocess.run([str(exe), "atlas", str(FACILITY), *QUICK, "--out", str(tmp_path / "o"),
                           "--workers", "1"], capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stderr.splitlines()
    start = [k for k, line in enumerate(lines)
             if "starting a local Dask cluster of 1 worker" in line]
    done = [k for k, line in enumerate(lines) if line.startswith("atlas: 1/2 pairs")]
    assert start and done and start[0] < done[0], proc.stderr
