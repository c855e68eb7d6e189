"""``pushtrain plan``: its output targets are checked before it plans (never a device or a
FIFO replaced, a missing folder made), and it says what it does while it plans."""

from __future__ import annotations

import io
import json
import os
import stat
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from pushtrain.cli.main import cli
from pushtrain.cli.progress import Phases

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
BAY = EXAMPLES / "bay.toml"


def _plan(*args):
    return CliRunner().invoke(cli, ["plan", str(BAY), *map(str, args)])


@pytest.mark.parametrize("option", ["--out", "--plot"])
def test_a_fifo_target_is_refused_before_planning_and_kept(tmp_path, option):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    done = _plan(option, fifo)
    assert done.exit_code == 2, done.output
    assert f"{option} {fifo}" in done.output and "not a regular file" in done.output
    assert "planning the path" not in done.output  # refused before the work
    assert stat.S_ISFIFO(fifo.stat().st_mode)


def test_a_folder_target_is_refused(tmp_path):
    done = _plan("--out", tmp_path)
    assert done.exit_code == 2 and "is a directory" in done.output, done.output


def test_out_in_a_missing_folder_makes_the_folder(tmp_path):
    target = tmp_path / "new" / "deeper" / "path.json"
    done = _plan("--out", target)
    assert done.exit_code == 0, done.output
    assert json.loads(target.read_text())


def test_an_out_that_cannot_be_written_is_refused_before_planning(tmp_path):
    done = _plan("--out", "/proc/pushtrain-plan/path.json")
    assert done.exit_code == 2, done.output
    assert "cannot be written" in done.output and "planning the path" not in done.output
    done = _plan("--out", tmp_path / ("p" * 250 + ".json"))
    assert done.exit_code == 2 and "too long" in done.output, done.output


def test_plan_says_that_it_plans(tmp_path):
    done = CliRunner().invoke(cli, ["plan", str(BAY)])
    assert done.exit_code == 0
    assert "planning the path" in done.output and "done: plan" in done.output


def test_a_long_phase_says_it_is_still_going():
    stream = io.StringIO()
    phases = Phases(stream=stream)
    with phases.phase("plan", "planning the path", tick_s=0.05):
        time.sleep(0.3)
    lines = stream.getvalue().splitlines()
    still = [line for line in lines if "still planning the path" in line]
    assert len(still) >= 2, lines
    assert still[-1].rstrip().endswith("s so far")
    with phases.phase("save", "saving"):  # no ticks unless asked for
        time.sleep(0.1)
    assert not [line for line in stream.getvalue().splitlines() if "still saving" in line]


def test_the_phase_summary_gives_each_phase_in_seconds():
    ticks = iter([0.0, 1.0, 1.0, 1.25, 2.0, 2.0, 3.5])  # start; each phase: line, start, end
    phases = Phases(stream=io.StringIO(), clock=lambda: next(ticks))
    with phases.phase("plan", "planning"):
        pass
    with phases.phase("co-simulate", "co-simulating"):
        pass
    assert phases.summary() == "plan 0.25 s, co-simulate 1.50 s"
