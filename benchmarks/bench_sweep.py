"""Sweep throughput on Dask (issue 7's benchmark): runs per second against the number of workers.

Each run is a 60 s closed-loop co-simulation (3 trailers pushed 4.8 m along a line at 0.08 m/s
with a 5 deg bias on joint 3: 12,000 steps). Measures

* the serial in-process time of one task (``run_sweep(serial=True)``: the same task function,
  metrics and chunk writing, no Dask),
* runs per second on a LocalCluster with 1 and 2 worker processes (more where the machine has
  more cores), after a warm-up batch that loads the modules and the FMU on every worker,
* the scaling efficiency rate(w) / (w rate(1)) and the per-task overhead of Dask, i.e. the wall
  time per run on 1 worker minus the serial time per run, against the serial time per run; and,
  apart from CPU contention, the dispatch overhead (wall time per run minus the task's own time
  measured inside the worker) and how busy the workers were.

Targets: efficiency >= 80 % at 2 workers; overhead below 5 % of a 60 s scenario's run time.

Run: python benchmarks/bench_sweep.py [--runs N]
"""

import argparse
import logging
import os
import tempfile
import time

from pushtrain.mission.scenario import parse_scenario
from pushtrain.studies.sweep import parse_sweep_spec, prepare_runs, run_sweep, run_task

BASE = {
    "name": "bench_60s",
    "mission": {"kind": "scripted"},
    "train": {"n": 3},
    "start": {"x": 0.0, "y": 0.0, "theta_deg": 180.0},
    "reference": {"speed": 0.08, "segments": [{"kind": "line", "length": 4.8}]},
    "sensors": {"localize": "last_trailer", "joint_bias_deg": [0.0, 0.0, 5.0]},
    "sim": {"settle_time": 0.0, "goal_tolerance": 0.2},
}


def _runs(n_runs: int):
    spec = parse_sweep_spec({"chunk_size": 8, "parameters": [
        {"path": "controller.k_y", "range": {"start": 3.5, "stop": 4.5, "num": n_runs}}]})
    runs, shared, _ = prepare_runs(parse_scenario(BASE, "bench"), spec)
    return spec, runs, shared


def _timed(runs, shared, spec, **kw) -> tuple[float, list[dict]]:
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        outcome = run_sweep(runs, run_task, out, metrics=spec.kept_metrics,
                            steady_window=spec.steady_window, chunk_size=spec.chunk_size,
                            shared=shared, **kw)
        wall = time.perf_counter() - t0
    assert outcome.complete and all(r["ok"] for r in outcome.rows), outcome.failures
    return wall, outcome.rows


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", type=int, default=16, help="runs per measurement")
    args = parser.parse_args()
    from distributed import Client, LocalCluster

    spec, runs, shared = _runs(args.runs)
    _timed(runs[:2], shared, spec, serial=True)  # warm-up: imports, FMU extraction paths
    serial_wall, rows = _timed(runs, shared, spec, serial=True)
    per_task = serial_wall / len(runs)
    print(f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores "
          "(other processes share the cores: compare with the load)")
    print(f"serial in-process: {len(runs)} runs in {serial_wall:.2f} s = {per_task * 1000:.1f} ms "
          f"per 60 s run ({1 / per_task:.2f} runs/s; co-simulation loop alone "
          f"{sum(r['wall_time_s'] for r in rows) / len(rows) * 1000:.1f} ms)")
    rates = {}
    counts = [1, 2] + [w for w in (4, 8) if w <= (os.cpu_count() or 1)]
    for workers in counts:
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                          dashboard_address=":0", silence_logs=logging.ERROR) as cluster, \
                Client(cluster) as client:
            _timed(runs[:2 * workers], shared, spec, client=client)  # warm-up on every worker
            wall, wrows = _timed(runs, shared, spec, client=client)
        rates[workers] = len(runs) / wall
        in_worker = sum(r["task_time_s"] for r in wrows) / len(wrows)
        line = (f"{workers} worker(s): {len(runs)} runs in {wall:.2f} s = "
                f"{rates[workers]:.2f} runs/s "
                f"(task time inside a worker {in_worker * 1000:.1f} ms)")
        busy = sum(r["task_time_s"] for r in wrows) / (workers * wall)
        line += f"; workers busy {busy * 100:.0f} % of the wall time"
        if workers == 1:
            dispatch = wall / len(runs) - in_worker
            line += (f"; Dask dispatch per task (wall per run - task time in the worker) "
                     f"{dispatch * 1000:+.1f} ms = {dispatch / per_task * 100:+.1f} % of a run")
            overhead = wall / len(runs) - per_task
            line += (f"; overhead per task {overhead * 1000:+.1f} ms = "
                     f"{overhead / per_task * 100:+.1f} % of a run")
        else:
            line += f"; scaling efficiency {rates[workers] / (workers * rates[1]) * 100:.0f} %"
        print(line)


if __name__ == "__main__":
    main()
