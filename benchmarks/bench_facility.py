"""Facility benchmark: missions of 15-80 m on public maps of real buildings.

Usage: python benchmarks/bench_facility.py [--budget 10] [--planners lattice,rrtconnect]
                                           [--only office] [--no-cosim] [--big-map]
                                           [--check 60] [--jobs 1]

The maps (``examples/maps/public``: a warehouse, a bookstore, an office floor; their sources and
licences in its README) and the missions (``benchmarks/facility/missions.toml``: stations where
the straight train fits, and for each mission the numbers of trailers to try) were drawn by
nobody here. Each mission runs in a process of its own (its peak memory is that process's, read
from ``os.wait4``), as ``plan-and-run`` would: plan, then co-simulate the FMU along the path,
then check every body against the map.

A mission counts as **feasible** when some planner has planned it and the co-simulation reached
the goal without a collision (a route verified by the FMU and the map check): in this run, or
in the larger-budget check (``--check SECONDS`` plans the missions that failed with that much
budget and records what it found in ``benchmarks/facility/feasibility.json``). A mission that
no planner has solved is reported as "not shown feasible", with the planner's reason; "impossible
here" reasons (no way of the train's width) are counted apart.

It prints one row per mission and planner, then for each planner: success on the feasible
missions (planned and co-simulated to the goal), median and p95 plan time, peak memory, and the
path's length over the route's length (:mod:`pushtrain.planner.route`). Targets (issue 28):
>= 95 % success, median <= 2 s, p95 <= 10 s, peak <= 1 GiB; no crash and nothing cut by the
clock. ``--big-map`` also plans on a 100 m x 100 m map at 5 cm and prints that process's peak
memory.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import time
import tomllib
from pathlib import Path

from bench_planner import percentile  # the benchmarks' one nearest-rank quantile

HERE = Path(__file__).resolve().parent
MISSIONS = HERE / "facility" / "missions.toml"
FEASIBILITY = HERE / "facility" / "feasibility.json"


def load_missions(path: Path = MISSIONS) -> list[dict]:
    """Every (mission, n) of the missions file as plain dicts with absolute map paths."""
    data = tomllib.loads(path.read_text())
    out = []
    for m in data["missions"]:
        stations = data["stations"][m["map"]]
        for n in m["trailers"]:
            out.append({"key": f"{m['map']}:{m['from']}->{m['to']}:n{n}", "map": m["map"],
                        "grid": str((path.parent / data["maps"][m["map"]]).resolve()),
                        "start": stations[m["from"]], "goal": stations[m["to"]], "n": n,
                        "route": m["route"]})
    return out


def scenario_of(mission: dict, planner: str, budget: float):
    """The plan-and-run scenario of one mission."""
    from pushtrain.mission.scenario import parse_scenario

    pose = ("x", "y", "theta_deg")
    return parse_scenario({
        "name": mission["key"].replace(":", "_").replace(">", ""),
        "mission": {"kind": "plan"}, "train": {"n": mission["n"]},
        "map": {"grid": mission["grid"]},
        "start": dict(zip(pose, mission["start"], strict=True)),
        "goal": dict(zip(pose, mission["goal"], strict=True)),
        "planner": {"planner": planner, "time_budget": budget},
    }, mission["key"])


def run_one(mission: dict, planner: str, budget: float, cosim: bool) -> dict:
    """Plan (and co-simulate) one mission in this process; a plain dict of what happened."""
    from pushtrain.errors import PlanningError
    from pushtrain.mission import runner
    from pushtrain.planner.route import find_route

    sc = scenario_of(mission, planner, budget)
    out = {"key": mission["key"], "planner": planner, "n": mission["n"]}
    t0 = time.perf_counter()  # the plan time includes reading the map and its distance field
    try:
        path = runner.plan_path(sc)
        out.update(plan_s=time.perf_counter() - t0, length_m=path.length, cusps=path.n_cusps,
                   capped=bool(path.info.get("time_capped")), status="planned")
    except PlanningError as exc:
        path = None
        out.update(status="no_plan", plan_s=time.perf_counter() - t0, reason=exc.reason,
                   message=str(exc)[:600], capped=bool(exc.details.get("time_capped")),
                   impossible=bool(exc.details.get("impossible")))
    world = runner.world_of(sc)  # cached: the map the plan read
    route = find_route(world.distance_field(), mission["start"][:2], mission["goal"][:2],
                       0.5 * runner.train_of(sc).last.width + 0.05)
    out["route_m"] = None if route is None else route.length
    if path is None:
        return out
    if cosim:
        reference = path.to_reference(speed=sc.planner.speed, cusp_dwell=sc.planner.cusp_dwell)
        t1 = time.perf_counter()
        result = runner.run_scenario(sc, None, reference=reference, progress=False)
        out.update(cosim_s=time.perf_counter() - t1, status=result.status,
                   message=result.message[:300],
                   final_lateral_m=(result.summary.get("lateral_error_m") or {}).get("final"),
                   min_clearance_m=(result.summary.get("map_check") or {}).get("min_clearance_m"))
    return out


def big_map(budget: float) -> dict:
    """Plan across a 100 m x 100 m occupancy grid at 5 cm (4 million cells): rack rows every
    10 m with cross aisles every 25 m, as a map file would give it (traced walls and all)."""
    import numpy as np

    from pushtrain.facility.loading import grid_world
    from pushtrain.facility.occupancy_grid import OccupancyGrid
    from pushtrain.planner.config import PlannerConfig
    from pushtrain.planner.planner import plan
    from pushtrain.planner.train import Train

    h, size = 0.05, 100.0
    cells = int(size / h)
    blocked = np.zeros((cells, cells), dtype=bool)
    blocked[:, :2] = blocked[:, -2:] = blocked[:2, :] = blocked[-2:, :] = True
    for k in range(1, 10):
        y = int(k * 10.0 / h)
        blocked[y - 20:y + 20, :] = True
        for x in (12.5, 37.5, 62.5, 87.5):
            j = int(x / h)
            blocked[y - 20:y + 20, j - 40:j + 40] = False
    world = grid_world(OccupancyGrid(blocked, 0.5 * h, 0.5 * h, h))
    t0 = time.perf_counter()
    try:
        path = plan(world, (5.0, 5.0, math.pi), (95.0, 95.0, math.pi), Train.uniform(3),
                    PlannerConfig(time_budget=budget))
        status, length = "planned", path.length
    except Exception as exc:  # noqa: BLE001 - reported, the benchmark goes on
        status, length = f"{type(exc).__name__}: {str(exc)[:200]}", None
    return {"key": "big_map_100m", "planner": "lattice", "n": 3, "status": status,
            "plan_s": time.perf_counter() - t0, "length_m": length}


def in_child(args: list[str]) -> dict:
    """Run ``--one ...`` in a new process; its result plus its peak memory [MiB]."""
    proc = subprocess.Popen([sys.executable, __file__, "--one", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True)
    _, status, usage = os.wait4(proc.pid, 0)
    text = proc.stdout.read()
    proc.stdout.close()
    try:
        result = json.loads(text.strip().splitlines()[-1])
    except (IndexError, json.JSONDecodeError):
        result = {"status": "crashed", "message": f"exit status {status}, output {text[-300:]!r}"}
    result["peak_mib"] = usage.ru_maxrss / 1024.0
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--budget", type=float, default=10.0, help="planner.time_budget [s]")
    ap.add_argument("--planners", default="lattice,rrtconnect")
    ap.add_argument("--only", default=None, help="only missions whose key contains this")
    ap.add_argument("--no-cosim", action="store_true")
    ap.add_argument("--big-map", action="store_true")
    ap.add_argument("--check", type=float, default=None,
                    help="plan the missions no planner solved with this budget [s] and record "
                         "the feasible ones in facility/feasibility.json")
    ap.add_argument("--one", nargs=4, metavar=("INDEX", "PLANNER", "BUDGET", "COSIM"),
                    help=argparse.SUPPRESS)
    args = ap.parse_args()
    missions = load_missions()
    if args.one:
        index, planner, budget, cosim = args.one
        if index == "big":
            print(json.dumps(big_map(float(budget))))
        else:
            print(json.dumps(run_one(missions[int(index)], planner, float(budget),
                                     cosim == "1")))
        return
    known = json.loads(FEASIBILITY.read_text()) if FEASIBILITY.exists() else {}
    chosen = [(i, m) for i, m in enumerate(missions) if not args.only or args.only in m["key"]]
    planners = args.planners.split(",")
    rows = {p: [] for p in planners}
    print(f"{len(chosen)} missions, budget {args.budget:g} s, load "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores", flush=True)
    for i, m in chosen:
        for p in planners:
            r = in_child([str(i), p, str(args.budget), "0" if args.no_cosim else "1"])
            r.update(key=m["key"], planner=p)
            rows[p].append(r)
            ratio = (r["length_m"] / r["route_m"]) if r.get("length_m") and r.get(
                "route_m") else math.nan
            print(f"{m['key']:<58} {p:<10} {r.get('status', '?'):<13} "
                  f"plan {r.get('plan_s', math.nan):6.2f} s  {r.get('peak_mib', 0):5.0f} MiB  "
                  f"route {r.get('route_m') or math.nan:5.1f} m  path/route {ratio:4.2f}  "
                  f"{r.get('reason', '')}", flush=True)
            if r.get("status") == "goal_reached":
                known[m["key"]] = {"feasible": True, "by": f"{p}, budget {args.budget:g} s, "
                                   "co-simulated to the goal"}
    if args.check:
        for i, m in chosen:
            if known.get(m["key"], {}).get("feasible"):
                continue
            r = in_child([str(i), "lattice", str(args.check), "1"])
            print(f"check {m['key']:<52} budget {args.check:g} s: {r.get('status')} "
                  f"({r.get('plan_s', math.nan):.1f} s) {r.get('message', '')[:160]}", flush=True)
            known[m["key"]] = {"feasible": r.get("status") == "goal_reached",
                               "by": f"lattice, budget {args.check:g} s: {r.get('status')}",
                               "reason": r.get("reason"), "impossible": r.get("impossible")}
        tmp = FEASIBILITY.with_suffix(".json.part")
        tmp.write_text(json.dumps(dict(sorted(known.items())), indent=1) + "\n")
        tmp.replace(FEASIBILITY)
    print()
    for p, rs in rows.items():
        feasible = [r for r in rs if known.get(r["key"], {}).get("feasible")]
        ok = [r for r in feasible if r.get("status") == "goal_reached"]
        times = [r["plan_s"] for r in rs if "plan_s" in r]
        ratios = [r["length_m"] / r["route_m"] for r in ok if r.get("route_m")]
        crashed = sum(r.get("status") == "crashed" for r in rs)
        capped = sum(bool(r.get("capped")) for r in rs)
        infeasible = [r for r in rs if r not in feasible]
        print(f"{p}: {len(ok)}/{len(feasible)} feasible missions planned and co-simulated to the "
              f"goal ({100 * len(ok) / max(1, len(feasible)):.0f} %, target >= 95 %); "
              f"plan time median {statistics.median(times) if times else math.nan:.2f} s "
              f"(target <= 2), p95 {percentile(times, 0.95):.2f} s (target <= 10); peak "
              f"{max((r['peak_mib'] for r in rs), default=0):.0f} MiB (target <= 1024); "
              f"path/route median {statistics.median(ratios) if ratios else math.nan:.2f}; "
              f"{crashed} crashed, {capped} cut by the clock; {len(infeasible)} not shown "
              f"feasible, of them {sum(bool(r.get('impossible')) for r in infeasible)} "
              "'impossible here'")
    if args.big_map:
        r = in_child(["big", "lattice", str(args.budget), "0"])
        print(f"100 m x 100 m map at 5 cm (4 million cells), n = 3, 127 m across: {r['status']}, "
              f"plan {r.get('plan_s', math.nan):.2f} s, peak {r['peak_mib']:.0f} MiB "
              "(target <= 1024)")


if __name__ == "__main__":
    main()
