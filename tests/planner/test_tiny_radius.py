"""A turning radius far below the train's (issue #29, case 5): the planner's budget holds.

``turning_radius = 1e-6`` with ``time_budget = 2`` planned for 168-262 s ("5250 of 300000 steps
done, 1 expansions"): the smoothing's Reeds-Shepp shortcut recovered its curve's pieces by
walking it in steps of rho / 8, 68 million interpolations for 8.5 m, none of them charged to the
budget (the pieces are computed in closed form now: tests/planner/test_reeds_shepp.py). Scenarios
refuse such a radius (tests/mission/test_scenario.py); the library still takes it.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


_PLAN = """
import json, sys
from pushtrain.mission.runner import plan_path
from pushtrain.mission.scenario import load_scenario

sc = load_scenario(sys.argv[1])
sc = sc.model_copy(update={"planner": sc.planner.model_copy(
    update={"turning_radius": 1e-6, "time_budget": 0.5})})
try:
    path = plan_path(sc)
    out = {k: path.info[k] for k in ("steps", "budget_steps", "time_capped")}
except Exception as exc:  # a PlanningError is an answer too
    details = getattr(exc, "details", None) or {}
    out = {"error": str(exc), "steps": details.get("steps"),
           "time_capped": details.get("time_capped")}
print(json.dumps(out))
"""


def test_planning_with_a_tiny_radius_keeps_its_budget():
    """The l_corridor with turning_radius = 1e-6 m and time_budget = 0.5 s (75 000 steps, wall
    cap 15 s): it ends within its work, not at the wall-clock cap, and long before the
    minutes it took."""
    done = subprocess.run([sys.executable, "-c", _PLAN, str(EXAMPLES / "l_corridor.toml")],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr[-2000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["time_capped"] is False, out
    if "error" not in out:
        assert out["steps"] <= out["budget_steps"] == 75_000, out
    else:
        assert out["steps"] is not None and out["steps"] <= 75_000, out
