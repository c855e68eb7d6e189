"""``export-bag``'s input and output folders: what is not a run is refused naming the missing
file (exit 2), ``--out`` replaces only an earlier bag, and a bag is never half-written."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import yaml
from conftest import invoke_cli, short_run

from pushtrain.errors import InputError
from pushtrain.ros import messages
from pushtrain.ros.bag import export_bag


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    """A short scripted run (straight_push, 0.3 s, exit 1: the goal is not reached)."""
    base = tmp_path_factory.mktemp("run")
    result = invoke_cli(["run", short_run(base), "--no-plots", "--out", base / "run"])
    assert result.exit_code == 1, result.output
    return base / "run"


def _tree(folder: Path) -> dict:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def _topics(bag: Path) -> dict:
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    return {e["topic_metadata"]["name"]: e["message_count"]
            for e in info["topics_with_message_count"]}


def test_a_scripted_run_has_motion_but_no_plan_or_goal(run_dir, tmp_path):
    result = invoke_cli(["export-bag", run_dir, "--out", tmp_path / "bag"])
    assert result.exit_code == 0, result.output
    topics = _topics(tmp_path / "bag")
    assert set(topics) == {"/map", "/reference", "/tf", "/joint_states",
                           "/joint_states/measured", "/train_markers", "/cmd_vel",
                           "/tracking_error", "/summary"}
    assert topics["/tf"] == 61  # 0.3 s at 5 ms, both ends
    assert sorted(p.name for p in (tmp_path / "bag").iterdir()) == ["bag.mcap", "metadata.yaml"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]  # no temporary folder left


@pytest.mark.parametrize("missing", ["scenario.json", "results.npz"])
def test_a_folder_that_is_not_a_run_is_refused_naming_the_file(run_dir, tmp_path, missing):
    folder = tmp_path / "not_a_run"
    shutil.copytree(run_dir, folder)
    (folder / missing).unlink()
    result = invoke_cli(["export-bag", folder, "--out", tmp_path / "bag"])
    assert result.exit_code == 2, result.output
    assert missing in result.output and "not a" in result.output
    assert not (tmp_path / "bag").exists()


def test_an_empty_folder_and_a_missing_one_are_refused(tmp_path):
    (tmp_path / "empty").mkdir()
    for folder in (tmp_path / "empty", tmp_path / "nowhere"):
        result = invoke_cli(["export-bag", folder, "--out", tmp_path / "bag"])
        assert result.exit_code == 2, result.output
        assert "RUN_DIR" in result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty"]


def test_results_without_the_scenario_s_trailers_are_refused(run_dir, tmp_path):
    folder = tmp_path / "other_n"
    shutil.copytree(run_dir, folder)
    scenario = json.loads((folder / "scenario.json").read_text())
    scenario["train"]["n"] = 4
    (folder / "scenario.json").write_text(json.dumps(scenario))
    result = invoke_cli(["export-bag", folder, "--out", tmp_path / "bag"])
    assert result.exit_code == 2, result.output
    assert "x4" in result.output and "4 trailers" in result.output


@pytest.mark.parametrize("what", ["the run folder", "a folder of other files", "a file"])
def test_out_over_anything_but_a_bag_is_refused_and_left_alone(run_dir, tmp_path, what):
    if what == "the run folder":
        out = tmp_path / "run"
        shutil.copytree(run_dir, out)
        source = out
    else:
        source = run_dir
        out = tmp_path / "other"
        if what == "a file":
            out.write_text("notes")
        else:
            out.mkdir()
            (out / "notes.txt").write_text("mine")
    before = out.read_bytes() if out.is_file() else _tree(out)
    result = invoke_cli(["export-bag", source, "--out", out])
    assert result.exit_code == 2, result.output
    assert "--out" in result.output
    assert (out.read_bytes() if out.is_file() else _tree(out)) == before


def test_an_earlier_bag_is_replaced_whole(run_dir, tmp_path):
    out = tmp_path / "bag"
    assert invoke_cli(["export-bag", run_dir, "--out", out, "--rate", 10]).exit_code == 0
    assert _topics(out)["/tf"] == 4  # 0, 0.1, 0.2 and the last sample, 0.3 s
    result = invoke_cli(["export-bag", run_dir, "--out", out])
    assert result.exit_code == 0, result.output
    assert _topics(out)["/tf"] == 61
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]


@pytest.mark.parametrize("option", [["--rate", "5"], ["--epoch", "-1"], ["--out", ""]])
def test_bad_options_exit_2(run_dir, tmp_path, option):
    args = ["export-bag", run_dir] + (["--out", tmp_path / "bag"] if option[0] != "--out"
                                      else []) + option
    result = invoke_cli(args)
    assert result.exit_code == 2, result.output
    assert not (tmp_path / "bag").exists()


@pytest.mark.parametrize("earlier", [False, True])
def test_a_failure_while_writing_leaves_nothing_half_written(run_dir, tmp_path, monkeypatch,
                                                             earlier):
    out = tmp_path / "bag"
    if earlier:
        export_bag(run_dir, out, rate_hz=10.0)
    before = _tree(out) if earlier else None
    calls = {"n": 0}
    serialize = messages.serialize

    def failing(message):
        calls["n"] += 1
        if calls["n"] > 40:
            raise KeyboardInterrupt  # Ctrl-C in the middle of the messages
        return serialize(message)

    monkeypatch.setattr(messages, "serialize", failing)
    with pytest.raises(KeyboardInterrupt):
        export_bag(run_dir, out)
    assert calls["n"] > 40
    assert sorted(p.name for p in tmp_path.iterdir()) == (["bag"] if earlier else [])
    if earlier:
        assert _tree(out) == before


def test_the_library_says_which_file_is_missing(tmp_path):
    (tmp_path / "scenario.json").write_text("{}")
    with pytest.raises(InputError, match="results.npz"):
        export_bag(tmp_path, tmp_path / "bag")


def test_the_mcap_file_reads_record_by_record(run_dir, tmp_path):
    """Read sequentially (not through its index) with CRCs checked, the file is a ROS 2 MCAP
    whose statistics, channels and message count agree with metadata.yaml."""
    from mcap.records import Channel, Header, Message, Schema, Statistics
    from mcap.stream_reader import StreamReader

    assert invoke_cli(["export-bag", run_dir, "--out", tmp_path / "bag"]).exit_code == 0
    with open(tmp_path / "bag" / "bag.mcap", "rb") as f:
        records = list(StreamReader(f, validate_crcs=True).records)
    kinds = {}
    for record in records:
        kinds.setdefault(type(record), []).append(record)
    (header,) = kinds[Header]
    assert header.profile == "ros2"
    assert {s.encoding for s in kinds[Schema]} == {"ros2msg"}
    channels = {c.id: c.topic for c in kinds[Channel]}
    topics = _topics(tmp_path / "bag")
    assert set(channels.values()) == set(topics)
    (stats,) = kinds[Statistics]
    assert stats.message_count == len(kinds[Message]) == sum(topics.values())
    counted = {}
    for message in kinds[Message]:
        counted[channels[message.channel_id]] = counted.get(channels[message.channel_id], 0) + 1
    assert counted == topics
