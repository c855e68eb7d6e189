"""What ``plan-and-run`` costs, phase by phase and picture by picture, in CPU-seconds (issue 35).

Runs, each in a fresh Python process, after one warm-up run per configuration (FMU build cache,
matplotlib's font cache, the OS file cache):

* ``python -c "import pushtrain.cli.main"`` (the CLI's import) and ``python -c pass`` (the
  interpreter alone), ``--repeats`` times each;
* ``plan-and-run SCENARIO --out TMP`` with each configuration of pictures (default: the default
  command, ``--no-plots``, and ``--plots all --gif`` for comparison), ``--repeats`` times each,
  alternating the configurations so that a change of load touches them alike;
* a 50-trailer, 60 s scripted run (``pushtrain run``, no map), whose page is timed.

CPU time is user + system of the command and of every process it waited for (``wait4``):
on a shared machine it moves much less with the load than the wall time, which is printed
beside it with the 1-minute load average. The phases' CPU times (plan, co-simulate, save, the
page) are the command's own process's, as ``run.log`` records them; each picture's CPU time is
that of the process that drew it (``run.log``); "other" is the rest of the total (interpreter
start-up, imports, reading the scenario and the map, forking, exit).

It prints one table, medians over the repeats, a column per configuration, and the ratios to
the targets: the default command <= 2.0 CPU-s in all, of which drawing (the page and any
picture) <= 0.6; wall time <= 1.5 s on a quiet 2-core machine (judge it with the load); the
50-trailer page <= 0.5 CPU-s and <= 5 MB.

Run: python benchmarks/bench_plan_and_run.py [--scenario examples/l_corridor.toml] [--repeats 3]
                                             [--no-all]
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TARGET_CPU_S = 2.0
TARGET_DRAW_CPU_S = 0.6
TARGET_WALL_S = 1.5
TARGET_PAGE_50_CPU_S = 0.5
TARGET_PAGE_50_MB = 5.0
TARGET_IMPORT_CPU_S = 0.25

PHASES = ("plan", "co-simulate", "save", "page")
PICTURES = ("map.png", "inputs_joints.png", "tracking_error.png", "lateral_forces.png",
            "train.gif")
_PHASE_CPU = re.compile(r"phase CPU times \(this process\): (.*)$")
_DRAWN = re.compile(r"INFO \S+: (\S+) drawn in ([\d.]+) s \(CPU ([\d.]+) s\) by (.*)$")

FIFTY = """name = "fifty"
[mission]
kind = "scripted"
[train]
n = 50
[start]
x = 0.0
y = 0.0
theta_deg = 180.0
[reference]
speed = 0.08
segments = [{ kind = "line", length = 20.0 }]
[sim]
horizon = 60.0
"""
"""The 50-trailer, 60 s scripted run of issue 35 (no map: the page's cost is the data's)."""


def run_process(args: list[str], cwd: Path) -> dict:
    """Run ``args``; its wall time [s], CPU time of it and its children [s], peak RSS of the
    largest of them [MiB], exit code, output and the 1-minute load average at its start."""
    load = os.getloadavg()[0]
    with tempfile.TemporaryFile("w+") as out:
        t0 = time.perf_counter()
        proc = subprocess.Popen(args, stdout=out, stderr=subprocess.STDOUT, cwd=cwd)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        out.seek(0)
        text = out.read()
    return {"wall": wall, "cpu": usage.ru_utime + usage.ru_stime,
            "rss_mib": usage.ru_maxrss / 1024.0, "exit": os.waitstatus_to_exitcode(status),
            "output": text, "load": load}


def _from_log(out_dir: Path) -> dict[str, float]:
    """CPU time [s] of each phase (the command's process) and each picture (its process)."""
    found: dict[str, float] = {}
    log = out_dir / "run.log"
    for line in log.read_text().splitlines() if log.is_file() else []:
        match = _PHASE_CPU.search(line)
        if match:
            for item in match.group(1).split(", "):
                name, seconds = item.rsplit(" ", 2)[:2]
                found[name] = float(seconds)
        match = _DRAWN.search(line)
        if match:
            found[match.group(1)] = float(match.group(3))
            if match.group(4).startswith("plot process"):
                found["in plot processes"] = (found.get("in plot processes", 0.0)
                                              + float(match.group(3)))
    return found


def run_command(command: list[str], out_dir: Path) -> dict:
    """``command`` (a plan-and-run or run) into ``out_dir``; :func:`run_process`'s numbers
    plus the phases' and pictures' CPU times, the drawing's, the rest and the folder's size."""
    args = [sys.executable, "-c", "from pushtrain.cli.entry import pushtrain; pushtrain()",
            *command, "--out", str(out_dir)]
    run = run_process(args, out_dir.parent)
    if run["exit"] not in (0, 1):
        raise RuntimeError(f"{' '.join(command)} failed (exit {run['exit']}):\n{run['output']}")
    parts = _from_log(out_dir)
    drawing = parts.get("page", 0.0) + sum(parts.get(p, 0.0) for p in PICTURES)
    # the plots phase: this process drawing pictures (or waiting for the plot processes)
    in_phases = sum(parts.get(p, 0.0) for p in (*PHASES, "plots"))
    run.update(parts=parts, drawing=drawing,
               other=run["cpu"] - in_phases - parts.get("in plot processes", 0.0),
               size_mb=sum(p.stat().st_size for p in out_dir.iterdir()) / 1e6,
               page_mb=((out_dir / "report.html").stat().st_size / 1e6
                        if (out_dir / "report.html").is_file() else 0.0))
    return run


def _median(runs, key):
    values = [key(r) for r in runs]
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def _loads(runs) -> str:
    lo, hi = min(r["load"] for r in runs), max(r["load"] for r in runs)
    return f"{lo:.2f}" if f"{lo:.2f}" == f"{hi:.2f}" else f"{lo:.2f}-{hi:.2f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", default="examples/l_corridor.toml")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs of each command")
    parser.add_argument("--no-all", action="store_true",
                        help="leave out the --plots all --gif comparison")
    args = parser.parse_args()
    scenario = str(Path(args.scenario).resolve())
    configs = {"default": [], "--no-plots": ["--no-plots"]}
    if not args.no_all:
        configs["--plots all --gif"] = ["--plots", "all", "--gif"]
    print(f"plan-and-run {args.scenario}: {os.cpu_count()} cores, load average (1 min) "
          f"{os.getloadavg()[0]:.2f} before; CPU-seconds are user + system of the command and "
          "every process it waited for; medians of", args.repeats)
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp)
        imports = {"python -c pass": [], "import pushtrain.cli.main": []}
        for _ in range(args.repeats):
            imports["python -c pass"].append(run_process([sys.executable, "-c", "pass"], base))
            imports["import pushtrain.cli.main"].append(
                run_process([sys.executable, "-c", "import pushtrain.cli.main"], base))
        runs: dict[str, list[dict]] = {name: [] for name in configs}
        for extra in configs.values():  # warm-up
            run_command(["plan-and-run", scenario, *extra], base / "warm")
        for k in range(args.repeats):
            for name, extra in configs.items():
                runs[name].append(run_command(["plan-and-run", scenario, *extra],
                                              base / f"{k}-{len(runs[name])}-{name[2:6]}"))
        fifty = base / "fifty.toml"
        fifty.write_text(FIFTY)
        run_command(["run", str(fifty), "--plots", "none"], base / "fifty-warm")
        big = [run_command(["run", str(fifty)], base / f"fifty-{k}")
               for k in range(args.repeats)]
    print(f"load average after: {os.getloadavg()[0]:.2f}\n")

    import_cpu = _median(imports["import pushtrain.cli.main"], lambda r: r["cpu"])
    bare_cpu = _median(imports["python -c pass"], lambda r: r["cpu"])
    names = list(configs)
    width = max(20, *(len(n) + 2 for n in names))
    print(f"{'CPU-seconds':<26}" + "".join(f"{n:>{width}}" for n in names))

    def row(label, key, fmt="{:.3f}"):
        cells = []
        for name in names:
            value = _median(runs[name], key)
            cells.append(f"{'-' if value is None else fmt.format(value):>{width}}")
        print(f"{label:<26}" + "".join(cells))

    print(f"{'  (import CLI, alone)':<26}" + f"{import_cpu:>{width}.3f}"
          + f"   python -c pass: {bare_cpu:.3f}")
    for phase in PHASES:
        row(phase, lambda r, p=phase: r["parts"].get(p))
    for picture in PICTURES:
        row(picture, lambda r, p=picture: r["parts"].get(p))
    row("drawing (page + pictures)", lambda r: r["drawing"])
    row("other (start, imports, ...)", lambda r: r["other"])
    row("total CPU", lambda r: r["cpu"])
    row("wall [s]", lambda r: r["wall"], "{:.2f}")
    row("peak RSS [MiB]", lambda r: r["rss_mib"], "{:.0f}")
    row("run folder [MB]", lambda r: r["size_mb"], "{:.2f}")
    row("report.html [MB]", lambda r: r["page_mb"], "{:.2f}")
    print(f"{'load (1 min)':<26}" + "".join(f"{_loads(runs[n]):>{width}}" for n in names))

    default = runs["default"]
    cpu = _median(default, lambda r: r["cpu"])
    draw = _median(default, lambda r: r["drawing"])
    wall = _median(default, lambda r: r["wall"])
    page50 = _median(big, lambda r: r["parts"].get("page"))
    mb50 = _median(big, lambda r: r["page_mb"])
    print()
    print(f"import pushtrain.cli.main: {import_cpu:.3f} CPU-s = "
          f"{import_cpu / TARGET_IMPORT_CPU_S:.2f} x the {TARGET_IMPORT_CPU_S} target")
    print(f"default command: {cpu:.2f} CPU-s = {cpu / TARGET_CPU_S:.2f} x the {TARGET_CPU_S} "
          f"target; drawing {draw:.3f} CPU-s = {draw / TARGET_DRAW_CPU_S:.2f} x the "
          f"{TARGET_DRAW_CPU_S} target; wall {wall:.2f} s = {wall / TARGET_WALL_S:.2f} x the "
          f"{TARGET_WALL_S} s target (quiet machine; load here {_loads(default)})")
    print(f"50 trailers, 60 s scripted run: page {page50:.3f} CPU-s = "
          f"{page50 / TARGET_PAGE_50_CPU_S:.2f} x the {TARGET_PAGE_50_CPU_S} target, "
          f"{mb50:.2f} MB = {mb50 / TARGET_PAGE_50_MB:.2f} x the {TARGET_PAGE_50_MB} MB target "
          f"(whole command {_median(big, lambda r: r['cpu']):.2f} CPU-s; load {_loads(big)})")


if __name__ == "__main__":
    main()
