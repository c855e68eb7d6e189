"""A turning radius far below the train's (issue #29, case 5): the planner's budget holds.

``turning_radius = 1e-6`` with ``time_budget = 2`` planned for 168-262 s ("5250 of 300000 steps
done, 1 expansions"): the smoothing's Reeds-Shepp shortcut recovered its curve's pieces by
walking it in steps of rho / 8, 68 million interpolations for 8.5 m, none of them charged to the
budget. Scenarios refuse such a radius (tests/mission/test_scenario.py); the library still takes it.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pushtrain.planner.curves import ReedsSheppCurve
from pushtrain.planner.reeds_shepp import recover_primitives

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


class _TooManyCalls(Exception):
    pass


def _counted(curve, limit):
    calls = [0]

    def interp(t):
        calls[0] += 1
        if calls[0] > limit:
            raise _TooManyCalls(f"more than {limit} interpolations")
        return curve.interpolate(t)

    return interp, calls


@pytest.mark.parametrize("rho", [1e-6, 1e-4])
def test_the_recovery_of_a_tiny_radius_curve_takes_a_bounded_number_of_interpolations(rho):
    curve = ReedsSheppCurve(rho, (0.0, 0.0, 0.0), (8.0, 3.0, 1.0))
    interp, calls = _counted(curve, 20_000)
    pieces = recover_primitives(interp, curve.length, rho, tol=1e-7)
    assert sum(p.length for p in pieces) == pytest.approx(curve.length, abs=1e-6)
    # turn, straight, turn: the straight is nearly the whole way
    assert [p.turn for p in pieces][1] == "S" and pieces[1].length > 8.5
    assert calls[0] <= 20_000


def test_a_long_curve_is_still_recovered_exactly():
    """A curve so long (400 m at rho = 0.5 m) that the walk takes a step coarser than rho / 8
    still gives the pieces OMPL interpolates."""
    from pushtrain.planner.reeds_shepp import evaluate_primitives

    rho = 0.5
    a, b = (0.0, 0.0, 0.3), (300.0, 250.0, -2.0)
    curve = ReedsSheppCurve(rho, a, b)
    assert curve.length / 2000 > rho / 8
    pieces = recover_primitives(curve.interpolate, curve.length, rho)
    assert sum(p.length for p in pieces) == pytest.approx(curve.length, abs=1e-8)
    ts = np.linspace(0.0, 1.0, 801)
    ompl = np.array([curve.interpolate(t) for t in ts])
    ours = evaluate_primitives(a, pieces, rho, ts * curve.length)
    assert np.hypot(*(ours[:, :2] - ompl[:, :2]).T).max() < 1e-6
    assert np.abs(np.angle(np.exp(1j * (ours[:, 2] - ompl[:, 2])))).max() < 1e-6


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
