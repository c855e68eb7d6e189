"""Reading a ROS map_server YAML (:mod:`pushtrain.facility.map_server`) and the project's TOML
files: a key given twice is refused naming the key and both lines, never a silent last-wins."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from pushtrain.cli.main import cli
from pushtrain.errors import MapError, ScenarioError, SweepError
from pushtrain.facility.map_server import read_map_yaml

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
GOOD = ("image: site.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n")


def test_a_good_yaml_reads(tmp_path):
    path = tmp_path / "site.yaml"
    path.write_text(GOOD)
    assert read_map_yaml(path)["resolution"] == pytest.approx(0.05)


@pytest.mark.parametrize("extra, key, line", [
    ("resolution: 0.5\n", "'resolution'", 7),        # the last would win: ten times coarser
    ("origin: [9.0, 9.0, 0.0]\n", "'origin'", 7),
    ("image: other.pgm\n", "'image'", 7),
])
def test_a_key_given_twice_is_refused_naming_it(tmp_path, extra, key, line):
    path = tmp_path / "site.yaml"
    path.write_text(GOOD + extra)
    with pytest.raises(MapError) as info:
        read_map_yaml(path)
    text = str(info.value)
    assert f"the key {key} is given twice" in text and f"line {line}" in text, text
    assert "each key once" in text


def test_a_key_twice_in_a_nested_mapping_is_refused(tmp_path):
    path = tmp_path / "site.yaml"
    path.write_text(GOOD + "extra:\n  a: 1\n  a: 2\n")
    with pytest.raises(MapError, match="the key 'a' is given twice"):
        read_map_yaml(path)


def test_through_the_cli_it_is_exit_2_naming_the_map_file(tmp_path):
    (tmp_path / "site.yaml").write_text(GOOD + "resolution: 0.5\n")
    scenario = tmp_path / "site.toml"
    scenario.write_text('[mission]\nkind = "plan"\n[train]\nn = 1\n[map]\ngrid = "site.yaml"\n'
                        "[start]\nx = 1.0\ny = 1.0\ntheta_deg = 180.0\n"
                        "[goal]\nx = 3.0\ny = 1.0\ntheta_deg = 180.0\n")
    done = CliRunner().invoke(cli, ["validate", str(scenario)])
    assert done.exit_code == 2, done.output
    assert "site.yaml" in done.output and "'resolution' is given twice" in done.output
    assert "goal" not in done.output  # the error no longer blames the goal


@pytest.mark.parametrize("loader, error", [
    ("pushtrain.mission.scenario:load_scenario", ScenarioError),
    ("pushtrain.studies.sweep_spec:load_sweep_spec", SweepError),
    ("pushtrain.studies.atlas:load_facility", ScenarioError),
])
def test_toml_files_refuse_a_key_given_twice(tmp_path, loader, error):
    """tomllib refuses duplicates itself (TOML 1.0 forbids them): every TOML the project reads
    goes through it (pushtrain.validation.read_toml)."""
    import importlib

    module, name = loader.split(":")
    path = tmp_path / "twice.toml"
    path.write_text('name = "a"\nname = "b"\n')
    with pytest.raises(error) as info:
        getattr(importlib.import_module(module), name)(path)
    text = str(info.value)
    assert "line 2" in text and "name = \"b\"" in text and "given twice" in text, text
