"""Whole-command benchmark of ``plan-and-run`` (issue 14): wall time per phase and peak memory.

Runs ``plan-and-run SCENARIO --out TMP`` in a fresh Python process, once to warm up (FMU build
cache, matplotlib's font cache, the OS file cache), then ``--repeats`` times, and reports for
each run and as medians:

* the wall time of the whole process (start-up and imports included) and its CPU time (user +
  system of the process and its plot processes, from ``wait4``: on a shared machine the CPU
  time moves less with the load than the wall time),
* the time of each phase as the command itself prints it on stderr (plan, co-simulate, save,
  plots: the wait for the plot processes after saving) and the rest (interpreter start-up, the
  CLI's imports, the scenario and map checks, exit),
* the peak resident memory (RSS) of each process: the command's own (main) process and each
  of the two plot processes that draw the PNGs and the GIF (as the command logs them in
  ``run.log``); ``wait4`` gives the largest of them,
* in separate, untimed runs (``--pss-runs``, default 1): the peak of the summed proportional
  memory (PSS, shared pages split between the processes that share them) of the whole process
  tree, sampled every 20 ms from ``/proc/PID/smaps_rollup``: what the command as a whole holds
  (the plot processes are forked, so most of their RSS is shared with the main process and
  counted in each RSS). The sampler is never on while a run is timed: reading
  ``smaps_rollup`` walks the measured process's page tables under its memory-map lock, and
  on 2 cores it made l_corridor's runs 26 % slower (medians of 5 alternating pairs, 6.25 s
  without, 7.90 s with, load 5.3-6.7; issue #29 saw 25-30 %),

and prints the ratios to the targets: wall time / 4 s and peak memory / 150 MiB (<= 1 meets
them), the memory judged on the largest single process's peak RSS (each process's peak is
printed, and the sum of the RSS peaks and the PSS peak of the tree for comparison).

Every figure is printed with the load average (1 min) it was measured at: the wall time grows
with the load (the CPU time less), so a figure without its load cannot be compared.

Run: python benchmarks/bench_plan_and_run.py [--scenario examples/l_corridor.toml] [--repeats 5]
                                             [--pss-runs 1]
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

TARGET_WALL_S = 4.0
TARGET_RSS_MIB = 150.0
_DONE = re.compile(r"^\[\s*([\d.]+) s\] done: (.*)$")
_PHASE = re.compile(r"^(.*) ([\d.]+) s$")
_PEAKS = re.compile(r"peak resident memory \[MiB\]: main process ([\d.]+), plot processes (.*)$")


def _tree(pid: int) -> list[int]:
    """``pid`` and its descendants (from /proc/PID/task/TID/children)."""
    found, todo = [], [pid]
    while todo:
        p = todo.pop()
        found.append(p)
        try:
            for task in os.listdir(f"/proc/{p}/task"):
                with open(f"/proc/{p}/task/{task}/children") as f:
                    todo += [int(c) for c in f.read().split()]
        except OSError:
            continue
    return found


def _pss_kib(pid: int) -> int:
    try:
        with open(f"/proc/{pid}/smaps_rollup") as f:
            for line in f:
                if line.startswith("Pss:"):
                    return int(line.split()[1])
    except (OSError, ValueError):
        pass
    return 0


class _TreePss:
    """Samples the summed PSS [KiB] of a process tree every ``interval`` s; ``peak`` the most."""

    def __init__(self, pid: int, interval: float = 0.02):
        self.pid, self.interval, self.peak = pid, interval, 0
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.stop.wait(self.interval):
            self.peak = max(self.peak, sum(_pss_kib(p) for p in _tree(self.pid)))

    def end(self) -> float:
        self.stop.set()
        self.thread.join()
        return self.peak / 1024.0


def run_once(scenario: str, out_dir: str, extra: list[str], sample_pss: bool = False) -> dict:
    """One ``plan-and-run`` in a new process: wall and CPU time [s] (CPU of the whole tree),
    peak RSS [MiB] of the largest process and of each (main first), the peak PSS of the tree
    [MiB] (with ``sample_pss`` only, else NaN: the sampler slows the run), the phase times [s]
    it printed, its exit code, and the load average (1 min) when it started."""
    code = "from pushtrain.cli.main import plan_and_run_main; plan_and_run_main()"
    args = [sys.executable, "-c", code, str(Path(scenario).resolve()), "--out", out_dir, *extra]
    load = os.getloadavg()[0]
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(args, stdout=out, stderr=err, cwd=Path(out_dir).parent)
        pss = (_TreePss(proc.pid) if sample_pss and os.path.exists(f"/proc/{proc.pid}/smaps_rollup")
               else None)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        pss_mib = pss.end() if pss is not None else float("nan")
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
    peaks = []  # main process, then the plot processes [MiB]
    log = Path(out_dir) / "run.log"
    for line in log.read_text().splitlines() if log.is_file() else []:
        match = _PEAKS.search(line)
        if match:
            peaks = [float(match.group(1))] + [float(v) for v in match.group(2).split(", ")]
    return {"wall": wall, "cpu": usage.ru_utime + usage.ru_stime,
            "rss_mib": usage.ru_maxrss / 1024.0, "peaks": peaks, "pss_mib": pss_mib,
            "phases": phases, "exit": proc.returncode, "load": load}


def _loads(runs) -> str:
    """``load a-b`` (1-minute load averages at the starts of ``runs``)."""
    lo, hi = min(r["load"] for r in runs), max(r["load"] for r in runs)
    return f"load {lo:.2f}" if f"{lo:.2f}" == f"{hi:.2f}" else f"load {lo:.2f}-{hi:.2f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", default="examples/l_corridor.toml")
    parser.add_argument("--repeats", type=int, default=5, help="timed runs (after a warm-up)")
    parser.add_argument("--pss-runs", type=int, default=1,
                        help="untimed runs with the 20 ms PSS sampler, after the timed ones")
    parser.add_argument("extra", nargs="*", help="more plan-and-run options (after --)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = str(Path(tmp) / "run")
        print(f"plan-and-run {args.scenario} {' '.join(args.extra)}".rstrip())
        print(f"{os.cpu_count()} cores; load average (1 min) {os.getloadavg()[0]:.2f} before "
              "(other processes share the cores: compare the loads printed)")
        run_once(args.scenario, out, args.extra)  # warm-up
        runs = []
        for k in range(args.repeats):
            run = run_once(args.scenario, out, args.extra)
            runs.append(run)
            phases = ", ".join(f"{name} {s:.2f}" for name, s in run["phases"].items())
            peaks = (f" (main {run['peaks'][0]:.0f}, plot processes "
                     f"{', '.join(f'{v:.0f}' for v in run['peaks'][1:])})" if run["peaks"] else "")
            print(f"run {k + 1} (load {run['load']:.2f}): wall {run['wall']:.2f} s, CPU "
                  f"{run['cpu']:.2f} s, peak RSS {run['rss_mib']:.0f} MiB{peaks}, exit "
                  f"{run['exit']} | {phases}")
        pss_runs = []
        for k in range(args.pss_runs):
            run = run_once(args.scenario, out, args.extra, sample_pss=True)
            pss_runs.append(run)
            print(f"PSS run {k + 1} (load {run['load']:.2f}, sampler on, not timed): tree PSS "
                  f"peak {run['pss_mib']:.0f} MiB (wall {run['wall']:.2f} s with the sampler)")
        size = sum(p.stat().st_size for p in Path(out).iterdir()) / 1e6
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    wall = statistics.median(r["wall"] for r in runs)
    cpu = statistics.median(r["cpu"] for r in runs)
    rss = max(r["rss_mib"] for r in runs)
    print("median phase times [s]: " + ", ".join(
        f"{name} {statistics.median(r['phases'][name] for r in runs):.2f}"
        for name in runs[0]["phases"]) + f" ({_loads(runs)})")
    print(f"run folder: {size:.1f} MB")
    print(f"wall time (median of {len(runs)}, sampler off): {wall:.2f} s = "
          f"{wall / TARGET_WALL_S:.2f} x the {TARGET_WALL_S:g} s target (CPU time {cpu:.2f} s = "
          f"{cpu / TARGET_WALL_S:.2f} x); {_loads(runs)} on {os.cpu_count()} cores")
    print(f"peak RSS of the largest process (largest of {len(runs)} runs, from wait4): "
          f"{rss:.0f} MiB = {rss / TARGET_RSS_MIB:.2f} x the {TARGET_RSS_MIB:g} MiB target")
    if all(r["peaks"] for r in runs):
        main_peak = max(r["peaks"][0] for r in runs)
        plot_peak = max(max(r["peaks"][1:], default=0.0) for r in runs)
        total = max(sum(r["peaks"]) for r in runs)
        print(f"  main process {main_peak:.0f} MiB = {main_peak / TARGET_RSS_MIB:.2f} x, largest "
              f"plot process {plot_peak:.0f} MiB = {plot_peak / TARGET_RSS_MIB:.2f} x; sum of the "
              f"processes' peaks {total:.0f} MiB (shared pages counted in each)")
    if pss_runs:
        pss = max(r["pss_mib"] for r in pss_runs)
        print(f"  peak PSS of the process tree (shared pages split, sampled every 20 ms in "
              f"{len(pss_runs)} untimed run(s)): {pss:.0f} MiB = {pss / TARGET_RSS_MIB:.2f} x; "
              f"{_loads(pss_runs)}")


if __name__ == "__main__":
    main()
