"""The click CLI: every command, --help, exit codes and error messages for bad input."""

import json
import math
from pathlib import Path

import pytest
from click.testing import CliRunner

from pushtrain.cli.main import cli

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
COMMANDS = [
    "plan-and-run", "plan", "run", "build-fmu", "analyze", "validate", "slip-study", "sweep",
    "export-bag",
]


@pytest.fixture
def runner():
    return CliRunner()


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_has_help_with_an_example(runner, command):
    result = runner.invoke(cli, [command, "--help"])
    assert result.exit_code == 0, result.output
    assert "Example" in result.output


def test_group_help_lists_the_commands(runner):
    result = runner.invoke(cli, ["--help"])
    assert result.exit_code == 0
    for command in COMMANDS:
        assert command in result.output


def _write(tmp_path, text, name="bad.toml"):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


BAD_SCENARIOS = {
    "wrong_type": ('[train]\nn = "three"\n', ["train.n", "'three'"]),
    "negative_mass": ('[train]\nn = 3\nmass = [42.1, -5.0, 42.1]\n', ["train.mass[1]", "-5.0"]),
    "unknown_key": ('[train]\nn = 3\nmas = 3.0\n', ["train.mas", "unknown key"]),
    "n_zero": ('[train]\nn = 0\n', ["train.n", "0"]),
    "anytime_time": ('[planner]\nanytime_time = 0\n', ["planner.anytime_time", "greater than 0"]),
    "pull_start": ('[planner]\npull_start_tolerance = -0.1\n',
                   ["planner.pull_start_tolerance", "-0.1"]),
}


@pytest.mark.parametrize("case", sorted(BAD_SCENARIOS))
def test_bad_scenarios_exit_2_naming_each_field_and_write_nothing(runner, tmp_path, case):
    text, needles = BAD_SCENARIOS[case]
    path = _write(tmp_path, text)
    out = tmp_path / "out"
    for command in (["validate", path], ["plan-and-run", path, "--out", str(out)]):
        result = runner.invoke(cli, command)
        assert result.exit_code == 2, result.output
        for needle in needles:
            assert needle in result.output, (needle, result.output)
    assert not out.exists(), "a rejected scenario must not leave an output folder"


def test_all_bad_fields_are_reported_at_once(runner, tmp_path):
    path = _write(tmp_path, '[train]\nn = 0\nmu = -1\n[controller]\nk_y = -2\n[sim]\nstepp = 1\n')
    result = runner.invoke(cli, ["validate", path])
    assert result.exit_code == 2
    for needle in ("train.n", "train.mu", "controller.k_y", "sim.stepp"):
        assert needle in result.output


def test_start_in_a_wall_exits_2(runner, tmp_path):
    text = (EXAMPLES / "l_corridor.toml").read_text()
    text = text.replace("x = 4.0\ny = 1.0", "x = 4.0\ny = 5.0")
    path = _write(tmp_path, text, "wall.toml")
    out = tmp_path / "out"
    result = runner.invoke(cli, ["plan-and-run", path, "--out", str(out)])
    assert result.exit_code == 2, result.output
    assert "start" in result.output and "free space" in result.output
    assert not out.exists()


def test_validate_accepts_every_example(runner):
    for path in sorted(EXAMPLES.glob("*.toml")):
        result = runner.invoke(cli, ["validate", str(path)])
        assert result.exit_code == 0, (path.name, result.output)


def test_validate_refuses_what_plan_and_run_refuses_before_it_searches(runner, tmp_path):
    """A goal that leaves the last trailer no clearance from the wall, and a goal behind an
    obstacle across the corridor (no way of the train's width): validate says so (exit 2) as
    plan-and-run does, with the same reason, and without searching."""
    corridor = (EXAMPLES / "l_corridor.toml").read_text()
    near = _write(tmp_path, corridor.replace("x = 8.0\ny = 7.5", "x = 8.7\ny = 7.5"), "near.toml")
    blocked = _write(tmp_path, corridor.replace(
        "free = [[0.0, 0.0], [9.0, 0.0], [9.0, 9.0], [7.0, 9.0], [7.0, 2.0], [0.0, 2.0]]",
        "free = [[0.0, 0.0], [9.0, 0.0], [9.0, 9.0], [7.0, 9.0], [7.0, 2.0], [0.0, 2.0]]\n"
        "obstacles = [[[7.0, 4.0], [9.0, 4.0], [9.0, 4.5], [7.0, 4.5]]]"), "blocked.toml")
    for path, reason, words in ((near, "goal_in_collision", "keeps only 0.000 m"),
                                (blocked, "unreachable", "impossible here")):
        checked = runner.invoke(cli, ["validate", path])
        assert checked.exit_code == 2, checked.output
        assert f"planning failed ({reason}): " in checked.output and words in checked.output
        assert f"[{reason}]" not in checked.output  # the reason once
        ran = runner.invoke(cli, ["plan-and-run", path, "--out", str(tmp_path / reason),
                                  "--no-plots"])
        assert ran.exit_code == 2 and f"planning failed ({reason}): " in ran.output, ran.output


def test_validate_without_a_c_compiler_is_not_a_bad_scenario(runner, tmp_path, monkeypatch):
    """The planner's checks need the engine's C: with no compiler (and no library built in
    this cache) validate says so and exits 1, as plan-and-run does, not 2 (the scenario is
    fine)."""
    monkeypatch.setenv("CC", "/nonexistent/bin/cc")
    monkeypatch.setenv("PUSHTRAIN_CACHE", str(tmp_path / "cache"))
    result = runner.invoke(cli, ["validate", str(EXAMPLES / "l_corridor.toml")])
    assert result.exit_code == 1, result.output
    assert "C compiler not found" in result.output


def test_the_version_is_the_installed_distributions(runner):
    from importlib.metadata import version

    result = runner.invoke(cli, ["--version"])
    assert result.exit_code == 0
    assert result.output.strip() == f"pushtrain {version('pushtrain')}"


def test_plan_writes_a_path_that_run_replays(runner, tmp_path):
    path_file = tmp_path / "path.json"
    png = tmp_path / "path.png"
    result = runner.invoke(cli, ["plan", str(EXAMPLES / "l_corridor.toml"), "--out", str(path_file),
                                 "--plot", str(png)])
    assert result.exit_code == 0, result.output
    assert "segments" in result.output
    data = json.loads(path_file.read_text())
    assert data["segments"]
    assert png.stat().st_size > 1000
    out = tmp_path / "run"
    result = runner.invoke(cli, ["run", str(EXAMPLES / "l_corridor.toml"), "--path", str(path_file),
                                 "--out", str(out), "--no-plots"])
    assert result.exit_code == 0, result.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "goal_reached"
    # the same path with another scenario: refused, naming --path and what differs
    other = tmp_path / "other"
    result = runner.invoke(cli, ["run", str(EXAMPLES / "bay.toml"), "--path", str(path_file),
                                 "--out", str(other), "--no-plots"])
    assert result.exit_code == 2, result.output
    assert "--path" in result.output and "is not the scenario's start (11.500, 1.500" in \
        result.output
    assert not other.exists()


def test_run_with_a_broken_path_file_exits_2(runner, tmp_path):
    bad = tmp_path / "path.json"
    bad.write_text('{"segments": "nope"}')
    result = runner.invoke(cli, ["run", str(EXAMPLES / "l_corridor.toml"), "--path", str(bad),
                                 "--out", str(tmp_path / "o")])
    assert result.exit_code == 2, result.output
    assert "path.json" in result.output


def test_run_of_a_plan_mission_without_path_exits_2(runner, tmp_path):
    result = runner.invoke(
        cli, ["run", str(EXAMPLES / "l_corridor.toml"), "--out", str(tmp_path / "o")]
    )
    assert result.exit_code == 2
    assert "--path" in result.output


def test_build_fmu_command(runner, tmp_path):
    out = tmp_path / "TT.fmu"
    result = runner.invoke(cli, ["build-fmu", "--trailers", "2", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert out.is_file()
    result = runner.invoke(cli, ["build-fmu", "--trailers", "0", "-o", str(out)])
    assert result.exit_code == 2
    assert "0" in result.output


def test_analyze_reports_stability_and_predicted_offset(runner):
    result = runner.invoke(cli, ["analyze", str(EXAMPLES / "joint_bias_5deg.toml")])
    assert result.exit_code == 0, result.output
    assert "stable" in result.output and "UNSTABLE" in result.output
    assert "-4.19 cm" in result.output  # sin(5 deg) / (0.52 * 4)


def test_plan_and_run_console_script_with_overrides(runner, tmp_path):
    out = tmp_path / "o"
    result = runner.invoke(cli, ["plan-and-run", str(EXAMPLES / "straight_push.toml"),
                                 "--out", str(out), "--trailers", "2", "--seed", "3",
                                 "--no-plots"])
    assert result.exit_code == 0, result.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["n_trailers"] == 2
    scenario = json.loads((out / "scenario.json").read_text())
    assert scenario["seed"] == 3 and scenario["train"]["n"] == 2
    assert (out / "run.log").stat().st_size > 0
    assert not list(out.glob(".*.part"))


def test_a_goal_no_way_reaches_exits_2_with_a_diagnostic_picture(runner, tmp_path):
    """A wall across the L's second leg: no way joins start and goal, proven from the map
    before any search ("impossible here"): the scenario asks for the impossible, which is bad
    input (exit 2), and the failure's picture, page and bag are written."""
    text = (EXAMPLES / "l_corridor.toml").read_text().replace(
        "free = [[0.0, 0.0], [9.0, 0.0], [9.0, 9.0], [7.0, 9.0], [7.0, 2.0], [0.0, 2.0]]",
        "free = [[0.0, 0.0], [9.0, 0.0], [9.0, 9.0], [7.0, 9.0], [7.0, 2.0], [0.0, 2.0]]\n"
        "obstacles = [[[7.0, 4.0], [9.0, 4.0], [9.0, 4.5], [7.0, 4.5]]]")
    path = _write(tmp_path, text, "blocked.toml")
    out = tmp_path / "out"
    result = runner.invoke(cli, ["plan-and-run", path, "--out", str(out), "--bag"])
    assert result.exit_code == 2, result.output
    assert "planning failed (unreachable)" in result.output and "impossible here" in result.output
    assert "[unreachable]" not in result.output  # the reason is said once
    assert (out / "planning_failure.png").is_file() and (out / "report.html").is_file()
    summary = json.loads((out / "summary.json").read_text())
    # a failed plan all the same: its status says so, and its bag (the map, the start) is made
    assert summary["exit_code"] == 2 and summary["status"] == "planning_failed"
    assert (out / "bag" / "metadata.yaml").is_file()


def test_a_search_that_finds_nothing_in_its_budget_exits_1(runner, tmp_path):
    """The T junction's K-turn is possible (the example plans it), but not within 0.01 s of
    budget: the search gave up, which says nothing against the scenario (exit 1)."""
    text = (EXAMPLES / "t_junction_kturn.toml").read_text()
    text = text.replace("[planner]\n", "[planner]\ntime_budget = 0.01\n") if "[planner]" in text \
        else text + "\n[planner]\ntime_budget = 0.01\n"
    path = _write(tmp_path, text, "short.toml")
    out = tmp_path / "out"
    result = runner.invoke(cli, ["plan-and-run", path, "--out", str(out)])
    assert result.exit_code == 1, result.output
    assert "planning failed (budget_exhausted)" in result.output
    assert (out / "planning_failure.png").is_file()


def test_a_goal_too_close_to_the_walls_exits_2_with_numbers_and_a_picture(runner, tmp_path):
    """The docking bay leaves 0.15 m beside the trailer; asking 0.2 m is the scenario's fault."""
    text = (EXAMPLES / "docking.toml").read_text().replace(
        "[planner]\n", "[planner]\nclearance = 0.2\n")
    path = _write(tmp_path, text, "tight.toml")
    out = tmp_path / "out"
    result = runner.invoke(cli, ["plan-and-run", path, "--out", str(out)])
    assert result.exit_code == 2, result.output
    assert "goal_in_collision" in result.output
    assert "keeps only 0.150 m from the walls; planner.clearance asks 0.200 m" in result.output
    assert (out / "planning_failure.png").stat().st_size > 10_000


def test_plan_and_run_console_script_usage_and_bad_option():
    import subprocess
    import sys

    exe = Path(sys.executable).with_name("plan-and-run")
    help_text = subprocess.run([str(exe), "-h"], capture_output=True, text=True)
    assert help_text.returncode == 0
    assert help_text.stdout.startswith("Usage: plan-and-run [OPTIONS] SCENARIO")
    bad = subprocess.run([str(exe), str(EXAMPLES / "bay.toml"), "--seed", "0"],
                         capture_output=True, text=True)
    assert bad.returncode == 2
    assert "Usage: plan-and-run [OPTIONS] SCENARIO" in bad.stderr and "--seed" in bad.stderr


def test_planner_settings_reach_the_planner(tmp_path, monkeypatch):
    """[planner] anytime_time and pull_start_tolerance are what plan() is given (monkeypatched
    plan records its configuration)."""
    import pushtrain.planner.planner as planner_module
    from pushtrain.mission.runner import plan_path
    from pushtrain.mission.scenario import load_scenario

    text = (EXAMPLES / "l_corridor.toml").read_text().replace(
        'time_budget = 2.0', 'time_budget = 2.0\nplanner = "restarts"\nanytime_time = 0.25\n'
        'pull_start_tolerance = 0.2\nclearance = [0.1, 0.05, 0.05, 0.06]\n'
        'pull_max_phi_deg = 20.0\njoint_margin_deg = 3.0\nstep_length = 0.4\n'
        'search_weight = 1.5\nsmooth = false')
    sc = load_scenario(_write(tmp_path, text, "settings.toml"))
    seen = {}

    def fake_plan(world, start, goal, train, config, start_headings=None):
        seen["config"] = config
        return "planned"

    monkeypatch.setattr(planner_module, "plan", fake_plan)
    assert plan_path(sc) == "planned"
    cfg = seen["config"]
    assert (cfg.planner, cfg.anytime_time, cfg.pull_start_tolerance) == ("restarts", 0.25, 0.2)
    assert cfg.clearance == (0.1, 0.05, 0.05, 0.06) and cfg.smooth is False
    assert cfg.pull_max_phi == pytest.approx(math.radians(20.0))
    assert cfg.joint_margin == pytest.approx(math.radians(3.0))
    assert (cfg.step_length, cfg.search_weight) == (0.4, 1.5)
    # the co-simulation's goal test is the planner's
    assert cfg.goal_tolerance == pytest.approx((sc.sim.goal_tolerance,
                                                math.radians(sc.sim.goal_heading_tolerance_deg)))


def test_ctrl_c_during_a_run_is_exit_130_with_a_summary_saying_so(tmp_path):
    """SIGINT once the run folder exists (planning the three-point turn): the console script
    ends with one line and exit code 130, not click's "Aborted!" and exit 1 (which means the
    goal was not reached); summary.json says "interrupted" and the files written are kept."""
    import json
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    scenario = Path(__file__).resolve().parents[2] / "examples" / "three_point_turn.toml"
    out = tmp_path / "out"
    code = ("import sys; from pushtrain.cli.entry import plan_and_run; "
            f"sys.argv = ['plan-and-run', {str(scenario)!r}, '--out', {str(out)!r}, "
            "'--no-plots']; plan_and_run()")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 120
    while not (out / "scenario.json").exists() and time.monotonic() < deadline:
        time.sleep(0.005)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "Aborted" not in err
    assert "interrupted (Ctrl-C)" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["exit_code"] == 130
    assert (out / "scenario.json").exists() and (out / "run.log").exists()


def test_the_readme_cli_block_lists_every_command():
    """The README's ``## CLI`` block names every command of ``pushtrain`` (it left out sweep)."""
    from pushtrain.cli.main import cli as group

    text = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    section = text[text.index("## CLI"):]
    block = section[section.index("```") + 3:]
    block = block[:block.index("```")]
    listed = {line.split()[1] for line in block.splitlines() if line.startswith("pushtrain ")}
    hidden = {name for name, cmd in group.commands.items() if cmd.hidden}
    assert set(group.commands) - hidden - listed == set()
