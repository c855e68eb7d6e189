"""pushtrain atlas: every answer replays with plan-and-run; the same answers serially and on
Dask; resumed after an interruption; bad facility files and options are exit 2."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FACILITY = ROOT / "examples" / "atlas" / "facility.toml"
SUBSET = "hall,recess,corridor"  # answers 0, 2, 4 and 5 among them


def _cli(*args):
    exe = Path(sys.executable).with_name("pushtrain")
    return subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True,
                          timeout=1800)


@pytest.fixture(scope="module")
def subset_atlas(tmp_path_factory):
    out = tmp_path_factory.mktemp("atlas") / "subset"
    proc = _cli("atlas", FACILITY, "--trailers", "1-5", "--stations", SUBSET, "--out", out,
                "--serial")
    assert proc.returncode == 0, proc.stderr[-2000:]
    return out, proc


@pytest.mark.slow
def test_every_answer_replays_with_plan_and_run(subset_atlas, tmp_path):
    out, proc = subset_atlas
    doc = json.loads((out / "atlas.json").read_text())
    answers = {(p["from"], p["to"]): p["max_trailers"] for p in doc["pairs"]}
    assert len(answers) == 6
    assert set(answers.values()) >= {0, 2, 5}  # the example's limits: a slit-free dead end,
    # an L corridor 1.1 m wide, the open hall
    assert "most trailers from (rows) to (columns)" in proc.stdout
    assert "about" in proc.stderr and "s left" in proc.stderr  # progress with an estimate
    for (a, b), k in answers.items():
        # a scenario file for every n, also those not tried after the first failure
        assert all((out / "missions" / f"{a}-{b}-n{n}.toml").is_file() for n in range(1, 6))
        for n, must_reach in ((k, True), (k + 1, False)):
            if n < 1 or n > 5:
                continue
            mission = out / "missions" / f"{a}-{b}-n{n}.toml"
            assert mission.is_file()
            run = _cli("plan-and-run", mission, "--out", tmp_path / f"{a}-{b}-n{n}",
                       "--no-plots")
            assert (run.returncode == 0) == must_reach, (mission.name, run.stdout[-800:],
                                                         run.stderr[-800:])
    rows = (out / "atlas.csv").read_text().splitlines()
    assert rows[0].startswith("from,to,max_trailers,n,status")
    assert len(rows) - 1 == sum(len(p["by_n"]) for p in doc["pairs"])
    for name in ("atlas.png", "matrix.png", "report.html"):
        assert (out / name).stat().st_size > 1000


@pytest.mark.slow
def test_dask_gives_the_serial_answers_and_a_rerun_resumes(subset_atlas, tmp_path):
    serial, _ = subset_atlas
    out = tmp_path / "dask"
    proc = _cli("atlas", FACILITY, "--trailers", "1-5", "--stations", "hall,recess",
                "--out", out, "--workers", "2")
    assert proc.returncode == 0, proc.stderr[-2000:]

    def answers(folder):
        doc = json.loads((folder / "atlas.json").read_text())
        return {(p["from"], p["to"]): (p["max_trailers"], {n: (r["status"], r["length_m"])
                                                            for n, r in p["by_n"].items()})
                for p in doc["pairs"]}

    got, want = answers(out), answers(serial)
    assert got == {k: v for k, v in want.items() if k in got}
    # an interrupted atlas: one pair's answer lost; the rerun computes only that pair
    (out / "pairs" / "recess-hall.json").unlink()
    kept = (out / "pairs" / "hall-recess.json").stat().st_mtime_ns
    again = _cli("atlas", FACILITY, "--trailers", "1-5", "--stations", "hall,recess",
                 "--out", out, "--serial")
    assert again.returncode == 0, again.stderr[-2000:]
    assert (out / "pairs" / "hall-recess.json").stat().st_mtime_ns == kept
    assert "atlas: 1/2 pairs" in again.stderr
    assert answers(out) == got


@pytest.mark.parametrize("edit, where", [
    (lambda t: t.replace('name = "bay_b"', 'name = "bay_a"'), "stations[1].name"),
    (lambda t: t.replace("x = 8.0", "x = nan"), "stations[2].x"),
    (lambda t: t.replace("x = 8.0", 'x = "8"'), "stations[2].x"),
    (lambda t: t.replace('name = "hall"', 'name = "../hall"'), "stations[2].name"),
    (lambda t: t.replace("[planner]", "[planer]"), "planer"),
    (lambda t: t.replace("time_budget = 4.0", "time_budget = -1"), "planner.time_budget"),
    (lambda t: t.replace("x = 8.0\ny = 4.5", "x = 80.0\ny = 4.5"), "hall"),
])
def test_a_bad_facility_is_exit_2_naming_the_field(tmp_path, edit, where):
    bad = tmp_path / "facility.toml"
    bad.write_text(edit(FACILITY.read_text()))
    proc = _cli("atlas", bad, "--out", tmp_path / "out", "--serial")
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert where in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "out" / "atlas.json").exists()


@pytest.mark.parametrize("args, where", [
    (["--trailers", "0-3"], "--trailers"),
    (["--trailers", "a"], "--trailers"),
    (["--stations", "hall"], "--stations"),
    (["--stations", "hall,nowhere"], "--stations"),
    (["--scheduler", "nonsense"], "--scheduler"),
])
def test_bad_options_are_exit_2(tmp_path, args, where):
    proc = _cli("atlas", FACILITY, "--out", tmp_path / "out", "--serial", *args)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert where in proc.stderr and "Traceback" not in proc.stderr


def test_an_out_folder_of_something_else_is_refused(tmp_path):
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    proc = _cli("atlas", FACILITY, "--out", other, "--stations", "hall,store", "--serial")
    assert proc.returncode == 2 and "--out" in proc.stderr
    assert (other / "notes.txt").read_text() == "mine"
    shutil.rmtree(other)


def test_a_mission_whose_co_simulation_fails_is_a_row_not_a_lost_atlas(monkeypatch):
    import pushtrain.mission.runner as runner
    from pushtrain.errors import CosimError
    from pushtrain.studies.atlas import load_facility, run_pair

    def broken(*args, **kwargs):
        raise CosimError("the FMU could not be loaded")

    monkeypatch.setattr(runner, "run_scenario", broken)
    answer = run_pair(load_facility(FACILITY), "hall", "recess", (1, 2))
    assert answer["max_trailers"] == 0 and list(answer["by_n"]) == ["1"]
    assert answer["by_n"]["1"]["status"] == "error"
    assert answer["by_n"]["1"]["reason"] == "CosimError"
    assert "could not be loaded" in answer["failure"]["message"]


def test_the_pair_keeps_the_shape_of_its_best_n_and_the_failure_of_the_first_failing_n(
        monkeypatch):
    """n = 1 and 2 reach the goal, n = 3 collides: the pair's answer is 2, atlas.png draws
    the path of n = 2 (not the failing n's), and the failure is n = 3's; n = 4 is not tried."""
    import pushtrain.studies.atlas as atlas_mod
    from pushtrain.studies.atlas import load_facility, run_pair

    tried = []

    def mission(data):
        n = data["train"]["n"]
        tried.append(n)
        ok = n <= 2
        return {**dict.fromkeys(atlas_mod.RESULT_FIELDS),
                "status": "goal_reached" if ok else "collision",
                "path": [[float(n), 0.0], [float(n), 1.0]],
                "message": None if ok else f"trailer {n} leaves the free space"}

    monkeypatch.setattr(atlas_mod, "_one_mission", mission)
    answer = run_pair(load_facility(FACILITY), "hall", "recess", (1, 2, 3, 4))
    assert tried == [1, 2, 3]
    assert answer["max_trailers"] == 2
    assert answer["shape"]["path"] == [[2.0, 0.0], [2.0, 1.0]]
    assert answer["failure"]["n"] == 3 and "trailer 3" in answer["failure"]["message"]
    assert list(answer["by_n"]) == ["1", "2", "3"]
