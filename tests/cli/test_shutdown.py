"""How a real ``plan-and-run`` process ends when something stops it: SIGTERM (a batch scheduler,
``docker stop``) while it saves or plots, a full disk while it saves, a second run into the
folder it is writing.

Each run is a real console-script process. Where the test must act at a given moment, a hook
patched into the process (before the CLI loads) holds it there and says so on stderr; the test
waits for that line, never for a time, so a busy machine cannot make it act too early or too
late.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from pushtrain.files import RUN_MARKER

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
STRAIGHT = str(EXAMPLES / "straight_push.toml")  # scripted, reaches its goal: no planning
WATCHDOG_S = 600.0
"""A process that neither says what the test waits for nor ends in this long is killed (the
test then fails): a safety net for a hang, not a timing the test depends on."""

HOLD = """
import sys, time
def hold(what):
    print(f"holding {what}", file=sys.stderr, flush=True)
    while True:
        time.sleep(1.0)
"""
HOLD_IN_SAVE = HOLD + """
from pushtrain.cosim import result as results
def held_npz(partial, data):
    with open(partial, "wb") as f:  # half a file, as an interrupted write leaves it
        f.write(b"PK partial")
    hold("results.npz")
results.write_npz = held_npz
"""
HOLD_IN_PLOT = HOLD + """
from pushtrain.cli import plotting
drawn = plotting._draw
def held_draw(name, data, run):
    if name == "map.png":
        hold(name)
    return drawn(name, data, run)
plotting._draw = held_draw
"""


def _kill_group(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except OSError:
        pass


@pytest.fixture
def start():
    """``start(patch, args)``: ``plan-and-run ARGS`` as the console script runs it, with
    ``patch`` run first, in a process group of its own (killed at the end of the test, so a
    failed test leaves no held process behind)."""
    started = []

    def run(patch: str, args) -> subprocess.Popen:
        code = (patch + "\nimport sys\nfrom pushtrain.cli.entry import plan_and_run\n"
                f"sys.argv = ['plan-and-run', *{[str(a) for a in args]!r}]\nplan_and_run()\n")
        proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, start_new_session=True)
        proc.watchdog = threading.Timer(WATCHDOG_S, _kill_group, (proc,))
        proc.watchdog.daemon = True
        proc.watchdog.start()
        started.append(proc)
        return proc

    yield run
    for proc in started:
        proc.watchdog.cancel()
        _kill_group(proc)
        proc.communicate()


def _wait_for(proc: subprocess.Popen, needle: str) -> list[str]:
    """The stderr lines of ``proc`` up to the first that holds ``needle`` (it must come)."""
    lines = []
    for line in proc.stderr:
        lines.append(line)
        if needle in line:
            return lines
    proc.wait()
    pytest.fail(f"the process ended (exit {proc.returncode}) before saying {needle!r}:\n"
                + "".join(lines))


def _finish(proc: subprocess.Popen, before=()) -> tuple[str, str]:
    out, err = proc.communicate()  # the watchdog ends a hang
    return out, "".join(before) + err


def _children() -> dict[int, list[int]]:
    """{pid: the pids of its children} of every process now (Linux /proc)."""
    tree: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            ppid = int(stat.rsplit(")", 1)[1].split()[1])
            tree.setdefault(ppid, []).append(int(entry.name))
    return tree


def _descendants(pid: int) -> list[int]:
    tree, found, todo = _children(), [], [pid]
    while todo:
        for child in tree.get(todo.pop(), []):
            found.append(child)
            todo.append(child)
    return found


def _running(pid: int) -> bool:
    """Whether ``pid`` is a live process (a zombie has ended)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _hidden(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith(".")
                  and p.name != RUN_MARKER)


linux_only = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")


# -------------------------------------------------------------------------------------- SIGTERM
@linux_only
def test_sigterm_while_saving_is_exit_143_interrupted_and_no_partial_file(tmp_path, start):
    """SIGTERM while results.npz is half written: exit 143 with one line, summary.json says
    ``interrupted`` (with the co-simulation's numbers), no partial file, no plot process."""
    out = tmp_path / "out"
    proc = start(HOLD_IN_SAVE, [STRAIGHT, "--out", out, "--plots", "all", "--gif",
                             "--plot-processes", "2"])
    before = _wait_for(proc, "holding results.npz")
    plot_processes = _descendants(proc.pid)
    assert list(out.glob(".results.npz.*.part")), "the hook writes half a file first"
    proc.send_signal(signal.SIGTERM)
    _, err = _finish(proc, before)
    assert proc.returncode == 143, err
    assert "Traceback" not in err and "Exception ignored" not in err, err
    assert "terminated (SIGTERM)" in err and str(out) in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["exit_code"] == 143, summary
    assert summary["run_status"] == "goal_reached" and "lateral_error_m" in summary
    assert not (out / "results.npz").exists()
    assert _hidden(out) == [], "no partial file is left"
    assert [pid for pid in plot_processes if _running(pid)] == []


@linux_only
@pytest.mark.parametrize("to_group", [False, True], ids=["to_the_process", "to_the_group"])
def test_sigterm_while_plotting_is_exit_143_and_leaves_whole_files_only(tmp_path, start, to_group):
    """SIGTERM while the plot processes draw (one held on map.png, the other drawing the GIF
    and the rest): exit 143, summary.json says ``interrupted`` (not the run's goal_reached,
    with pictures missing), every picture there is whole, no partial file, no plot process left.
    Sent to the main process (``docker stop``) or to the whole group (a batch scheduler)."""
    from PIL import Image

    out = tmp_path / "out"
    proc = start(HOLD_IN_PLOT, [STRAIGHT, "--out", out, "--plots", "all", "--gif",
                             "--plot-processes", "2"])
    before = _wait_for(proc, "holding map.png")
    plot_processes = _descendants(proc.pid)
    assert len(plot_processes) >= 2, plot_processes
    if to_group:
        os.killpg(proc.pid, signal.SIGTERM)
    else:
        proc.send_signal(signal.SIGTERM)
    _, err = _finish(proc, before)
    assert proc.returncode == 143, err
    assert "Traceback" not in err and "Exception ignored" not in err, err
    assert err.count("terminated (SIGTERM)") == 1, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["exit_code"] == 143, summary
    assert summary["run_status"] == "goal_reached"
    assert (out / "results.npz").is_file() and not (out / "map.png").exists()
    for picture in [*out.glob("*.png"), *out.glob("*.gif")]:
        with Image.open(picture) as image:
            image.verify()
    assert _hidden(out) == [], "no partial file is left"
    assert [pid for pid in plot_processes if _running(pid)] == []


# ------------------------------------------------------------------------------------ disk full
@linux_only
def test_disk_full_while_saving_is_one_line_exit_1_and_no_partial_file(tmp_path, start):
    """ENOSPC while results.npz is written (the plot processes already have the results):
    one line naming the file and the folder, exit 1, no traceback from any process, no
    partial file, no plot process left."""
    out = tmp_path / "out"
    patch = """
import errno, os
from pushtrain.cosim import result as results
def full_disk(partial, data):
    with open(partial, "wb") as f:
        f.write(b"PK partial")
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
results.write_npz = full_disk
"""
    proc = start(patch, [STRAIGHT, "--out", out, "--plots", "all", "--gif",
                             "--plot-processes", "2"])
    _, err = _finish(proc)
    assert proc.returncode == 1, err
    assert f"disk full while writing results.npz in {out}" in err, err
    assert "Traceback" not in err and "Exception ignored" not in err, err
    assert not (out / "results.npz").exists() and _hidden(out) == []


# -------------------------------------------------------------------------------- one run only
def test_a_second_run_into_a_folder_being_written_is_refused(tmp_path, start):
    """Run A holds while saving; run B into the same --out is exit 2 naming the folder and
    touches nothing; A, released, completes with its files; then the folder is free again."""
    from click.testing import CliRunner

    from pushtrain.cli.main import cli

    out = tmp_path / "out"
    release = tmp_path / "release"
    patch = f"""
import sys, time
from pathlib import Path
from pushtrain.cosim import result as results
write = results.write_npz
def held_npz(partial, data):
    print("holding results.npz", file=sys.stderr, flush=True)
    while not Path({str(release)!r}).exists():
        time.sleep(0.05)
    write(partial, data)
results.write_npz = held_npz
"""
    first = start(patch, [STRAIGHT, "--out", out, "--no-plots"])
    before = _wait_for(first, "holding results.npz")
    files = {p.name: p.read_bytes() for p in out.iterdir()}
    second = CliRunner().invoke(cli, ["run", STRAIGHT, "--no-plots", "--out", str(out)])
    assert second.exit_code == 2, second.output
    assert "--out" in second.output and str(out) in second.output
    assert "in use by another run" in second.output, second.output
    assert "Traceback" not in second.output
    assert {p.name: p.read_bytes() for p in out.iterdir()} == files
    release.touch()
    _, err = _finish(first, before)
    assert first.returncode == 0, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "goal_reached" and (out / "results.npz").is_file()
    again = CliRunner().invoke(cli, ["run", STRAIGHT, "--no-plots", "--out", str(out)])
    assert again.exit_code == 0, again.output


@linux_only
def test_sighup_while_saving_is_exit_129_interrupted_with_a_summary(tmp_path, start):
    """SIGHUP (the terminal or SSH session closed) while results.npz is half written: ended as
    SIGTERM is, exit 129, summary.json says ``interrupted``, no partial file."""
    out = tmp_path / "out"
    proc = start(HOLD_IN_SAVE, [STRAIGHT, "--out", out, "--no-plots"])
    before = _wait_for(proc, "holding results.npz")
    proc.send_signal(signal.SIGHUP)
    _, err = _finish(proc, before)
    assert proc.returncode == 129, err
    assert "Traceback" not in err and "hung up (SIGHUP)" in err, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["exit_code"] == 129, summary
    assert _hidden(out) == [], "no partial file is left"
