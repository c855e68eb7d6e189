"""Planner benchmark on the L-corridors (1.5 m, 2.0 m) and the bay.

Usage: python benchmarks/bench_planner.py [--seeds 20] [--best-seeds 5] [--worlds l_1.5,l_2.0,bay]

Budgets are work, not wall-clock time (``pushtrain.planner.budget``): 1 s of ``time_budget`` or
``anytime_time`` is 1000 motion checks (BIT*: 500), so every result here depends on the seeds
only; the times reported are wall-clock times of this machine.

Reports per world, over the seeds:
- success rate of the default planner (RRTConnect + simplification, last trailer only) within
  0.1 s and 0.5 s budgets (100 and 500 motion checks; without the train check; a solve whose
  path breaks a pull rule is re-solved within the budget), and the median time plan() takes
  to return it;
- path length of RRTConnect, and of each anytime planner after 0.5 s, relative to the best
  length found: by every anytime planner with a 2 s budget (over --best-seeds seeds) and by
  every other run of the benchmark; "within 3 %" counts over all seeds;
- median number of cusps;
- whole-train pass rate: the first plan passes the closed-loop train check (before
  replanning; also reported: the first OMPL solve, which may be re-solved with the next seed
  when its path breaks a pull rule that only the finished path shows), and plan()
  succeeds within its 2 s budget (after replanning).
"""

from __future__ import annotations

import argparse
import statistics
import time

from pushtrain.planner import PlannerConfig, PlanningError, Train, World, plan, worlds

ANYTIME = ("restarts", "rrtstar", "bitstar")


def _run(world, case, train, cfg):
    t0 = time.perf_counter()
    try:
        path = plan(world, case["start"], case["goal"], train, cfg)
    except PlanningError as exc:
        return None, time.perf_counter() - t0, exc
    return path, time.perf_counter() - t0, None


def bench(name: str, seeds: int, best_seeds: int) -> dict:
    case = worlds.CASES[name]()
    world = World.from_dict(case["world"])
    train = Train.uniform(3)
    out = {"world": name}
    for budget in (0.1, 0.5):
        ok, first, lengths, cusps = 0, [], [], []
        for seed in range(1, seeds + 1):
            # no train check, so the only re-solves are those of the pull rules
            cfg = PlannerConfig(seed=seed, time_budget=budget, check_train=False)
            path, _, _ = _run(world, case, train, cfg)
            if path is not None:
                ok += 1
                first.append(path.info["time"])  # includes re-solves of the pull rules
                lengths.append(path.length)
                cusps.append(path.n_cusps)
        out[f"success_{budget}"] = ok / seeds
        if budget == 0.5:
            out["median_first_s"] = statistics.median(first) if first else float("nan")
            out["rrtc_lengths"] = lengths
            out["median_cusps"] = statistics.median(cusps) if cusps else float("nan")
    def anytime_lengths(
        planner: str, n_seeds: int, solve_time: float, budget: float
    ) -> list[float]:
        lengths = []
        for seed in range(1, n_seeds + 1):
            cfg = PlannerConfig(planner=planner, seed=seed, anytime_time=solve_time,
                                time_budget=budget, check_train=False)
            path, _, _ = _run(world, case, train, cfg)
            if path is not None:
                lengths.append(path.length)
        return lengths

    # the reference length: the best of every anytime planner with a 2 s budget
    best = [x for p in ANYTIME for x in anytime_lengths(p, best_seeds, 2.0, 2.5)]
    any05 = {p: anytime_lengths(p, seeds, 0.5, 0.6) for p in ANYTIME}
    pool = best + [x for v in any05.values() for x in v] + out["rrtc_lengths"]
    b = min(pool) if pool else float("nan")
    out["best_2s"] = min(best) if best else float("nan")
    out["best_any"] = b
    out["rrtc_excess_median"] = (
        (statistics.median(out["rrtc_lengths"]) / b - 1) if out["rrtc_lengths"] else float("nan")
    )
    for p, lengths in any05.items():
        out[f"{p}_found"] = len(lengths) / seeds
        # within 3 % of the best, counted over all seeds (a seed without a path fails)
        out[f"{p}_within3"] = sum(x <= 1.03 * b for x in lengths) / seeds
        out[f"{p}_excess_median"] = (
            (statistics.median(lengths) / b - 1) if lengths else float("nan")
        )
    before, first_solve, after, times, reasons, blocked = 0, 0, 0, [], {}, 0
    for seed in range(1, seeds + 1):
        path, dt, exc = _run(world, case, train, PlannerConfig(seed=seed, time_budget=2.0))
        times.append(dt)
        if path is not None:
            after += 1
            att = path.info["attempts"]
        else:
            reasons[exc.reason] = reasons.get(exc.reason, 0) + 1
            att = exc.details.get("attempts", [])
        # "before replanning": the first plan the planner produced (OMPL solves whose path
        # broke one of the planner's own pull rules on the finished path are re-solved with the
        # next seed and produce no plan; they are counted separately)
        checked = [a for a in att if "train_ok" in a]
        before += int(bool(checked) and checked[0]["train_ok"])
        first_solve += int(bool(att) and att[0].get("train_ok", False))
        blocked += sum(a.get("error") in ("pull_end_blocked", "pull_start_mismatch") for a in att)
    out["train_pass_before"] = before / seeds
    out["train_pass_first_solve"] = first_solve / seeds
    out["pull_end_resolves"] = blocked
    out["train_pass_after"] = after / seeds
    out["median_full_plan_s"] = statistics.median(times)
    out["failures"] = reasons
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--best-seeds", type=int, default=5)
    parser.add_argument("--worlds", default="l_1.5,l_2.0,bay")
    args = parser.parse_args()
    rows = [bench(w, args.seeds, args.best_seeds) for w in args.worlds.split(",")]
    print(f"seeds: {args.seeds}; reference length: best of every anytime planner "
          f"({', '.join(ANYTIME)}) with 2 s on {args.best_seeds} seeds, and of everything else")
    print("| world | ok<=0.1s | ok<=0.5s | median plan() [s] | RRTC len vs best | "
          + " | ".join(f"{p} 0.5 s: within 3 % (found)" for p in ANYTIME)
          + " | best [m] | cusps | train pass: first plan / first solve / after replanning | "
          "pull-rule re-solves | median plan() with check [s] | failures |")
    print("|---" * (11 + len(ANYTIME)) + "|")
    for r in rows:
        anytime = " | ".join(f"{r[p + '_within3']:.0%} ({r[p + '_found']:.0%})" for p in ANYTIME)
        print(f"| {r['world']} | {r['success_0.1']:.0%} | {r['success_0.5']:.0%} | "
              f"{r['median_first_s']:.3f} | +{r['rrtc_excess_median']:.1%} | {anytime} | "
              f"{r['best_any']:.2f} | {r['median_cusps']:.0f} | "
              f"{r['train_pass_before']:.0%} / {r['train_pass_first_solve']:.0%} / "
              f"{r['train_pass_after']:.0%} | {r['pull_end_resolves']} | "
              f"{r['median_full_plan_s']:.2f} | {r['failures']} |")


if __name__ == "__main__":
    main()
