"""Whole-command benchmark of ``plan-and-run`` (issue 14): wall time per phase and peak memory.

Runs ``plan-and-run SCENARIO --out TMP`` in a fresh Python process, once to warm up (FMU build
cache, matplotlib's font cache, the OS file cache), then ``--repeats`` times, and reports for
each run and as medians:

* the wall time of the whole process (start-up and imports included) and its CPU time (user +
  system, from ``wait4``: on a shared machine the CPU time moves less with the load than the
  wall time),
* the time of each phase as the command itself prints it on stderr (plan, co-simulate, save,
  plots, gif) and the rest (interpreter start-up, the CLI's imports, exit),
* the peak resident memory of the process (``ru_maxrss`` from ``wait4``),

and prints the ratios to the targets: wall time / 4 s and peak memory / 150 MiB (<= 1 meets
them).

Run: python benchmarks/bench_plan_and_run.py [--scenario examples/l_corridor.toml] [--repeats 3]
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

TARGET_WALL_S = 4.0
TARGET_RSS_MIB = 150.0
_DONE = re.compile(r"^\[\s*([\d.]+) s\] done: (.*)$")
_PHASE = re.compile(r"^(.*) ([\d.]+) s$")


def run_once(scenario: str, out_dir: str, extra: list[str]) -> dict:
    """One ``plan-and-run`` in a new process: wall and CPU time [s], peak RSS [MiB], the phase
    times [s] it printed, and its exit code."""
    code = "from pushtrain.cli.main import plan_and_run_main; plan_and_run_main()"
    args = [sys.executable, "-c", code, str(Path(scenario).resolve()), "--out", out_dir, *extra]
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(args, stdout=out, stderr=err, cwd=Path(out_dir).parent)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        stderr = err.read()
    phases = {}
    for line in stderr.splitlines():
        match = _DONE.match(line)
        if match:
            for item in match.group(2).split(", "):
                name, seconds = _PHASE.match(item).groups()
                phases[name] = float(seconds)
    if proc.returncode not in (0, 1):
        raise RuntimeError(f"plan-and-run failed (exit {proc.returncode}):\n{stderr}")
    phases["rest"] = wall - sum(phases.values())  # start-up, imports, exit (all if no phases)
    return {"wall": wall, "cpu": usage.ru_utime + usage.ru_stime,
            "rss_mib": usage.ru_maxrss / 1024.0, "phases": phases, "exit": proc.returncode}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", default="examples/l_corridor.toml")
    parser.add_argument("--repeats", type=int, default=3, help="measured runs (after a warm-up)")
    parser.add_argument("extra", nargs="*", help="more plan-and-run options (after --)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = str(Path(tmp) / "run")
        print(f"plan-and-run {args.scenario} {' '.join(args.extra)}".rstrip())
        print(f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores "
              "(other processes share the cores: compare with the load)")
        run_once(args.scenario, out, args.extra)  # warm-up
        runs = []
        for k in range(args.repeats):
            run = run_once(args.scenario, out, args.extra)
            runs.append(run)
            phases = ", ".join(f"{name} {s:.2f}" for name, s in run["phases"].items())
            print(f"run {k + 1}: wall {run['wall']:.2f} s, CPU {run['cpu']:.2f} s, peak RSS "
                  f"{run['rss_mib']:.0f} MiB, exit {run['exit']} | {phases}")
        size = sum(p.stat().st_size for p in Path(out).iterdir()) / 1e6
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    wall = statistics.median(r["wall"] for r in runs)
    cpu = statistics.median(r["cpu"] for r in runs)
    rss = max(r["rss_mib"] for r in runs)
    print("median phase times [s]: " + ", ".join(
        f"{name} {statistics.median(r['phases'][name] for r in runs):.2f}"
        for name in runs[0]["phases"]))
    print(f"run folder: {size:.1f} MB")
    print(f"wall time (median of {len(runs)}): {wall:.2f} s = {wall / TARGET_WALL_S:.2f} x the "
          f"{TARGET_WALL_S:g} s target (CPU time {cpu:.2f} s = {cpu / TARGET_WALL_S:.2f} x)")
    print(f"peak RSS (largest of {len(runs)}): {rss:.0f} MiB = {rss / TARGET_RSS_MIB:.2f} x the "
          f"{TARGET_RSS_MIB:g} MiB target")


if __name__ == "__main__":
    main()
