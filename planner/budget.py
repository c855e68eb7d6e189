"""Work budgets of the planner: counted work decides where a search stops, not the clock.

A search stops when it has done a given amount of work, so that a seed gives the same plan on
any machine and under any load. The unit is one *motion check*: the validation of one local
Reeds-Shepp curve by the planner's motion validator (footprints every
``planning_resolution`` metres and the pull rules, about 1 ms), its main cost in every OMPL
planner, the simplification, the repair and the local search. A whole-train check of a plan
counts one unit per :data:`STEPS_PER_CHECK` simulated control steps.

The configuration gives budgets in seconds (``time_budget``, ``anytime_time``); they convert
at :data:`CHECKS_PER_SECOND`. The wall clock only stops a search as a safety cap
(``PlannerConfig.time_cap``); a search stopped by it marks :attr:`Work.capped` and logs a
warning, since its result then depends on the machine's speed. PRM* is the exception: OMPL's
PRM evaluates its termination condition on a second thread too, where a condition written in
Python deadlocks, so PRM* stops on OMPL's clock (its second thread makes its result depend on
timing anyway).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass

__all__ = ["CHECKS_PER_SECOND", "DEFAULT_SEARCH_SECONDS", "OMPL_DEFAULT_SECONDS",
           "STEPS_PER_CHECK", "STEPS_PER_SECOND", "Work", "checks_for", "default_steps",
           "steps_for"]

log = logging.getLogger(__name__)

CHECKS_PER_SECOND = {"rrtconnect": 1000, "restarts": 1000, "rrtstar": 1000, "bitstar": 500,
                     "prmstar": 1000}
"""Motion checks per second of budget, by planner: about what one core of a current laptop
validates per second in the bay and the L-corridors (measured 800-2000 per CPU second for
RRTConnect, the restarts and RRT*). BIT* checks as fast until its first solution; after it,
most of its time goes to work in OMPL that no check counts (2 m L-corridor: 250 checks 0.3 s,
500 checks 1.2-4.4 s, 1000 checks 8.7 s of CPU; its first solution there needs 250-400
checks), hence its lower rate. PRM* stops on the clock after ``checks / rate`` seconds
instead (see :func:`pushtrain.planner.ompl_search._termination`)."""

STEPS_PER_CHECK = 10
"""Simulated control steps (0.025 s each) of the whole-train check counted as one motion check
(measured 8 600-15 000 steps per CPU second when the check ran the closed loop in Python; it now
runs on the compiled engine and is dominated by its footprint tests, but the rate is kept so a
budget means the same work as before)."""


STEPS_PER_SECOND = 150_000
"""The whole-train search (``lattice``): simulated control steps per second of ``time_budget``,
about what the search does per CPU second with the compiled closed loop
(:class:`~pushtrain.planner.propagate.Propagator` on the engine: about 2 us per step with its
checks, plus the search's own work) for three trailers (three-point turn: 150 000 steps in
1.1 s of CPU)."""


DEFAULT_SEARCH_SECONDS = 20.0
"""The whole-train search's default budget (no ``time_budget`` given): about this many CPU
seconds of search on a current laptop core, whatever the number of trailers, counted in
simulated control steps (:func:`default_steps`). The search stops at its first plan, so the
budget only bounds a search that finds none: a mission that plans costs what it needs (median
about a second on the facility benchmark), and one that does not is given up after about 20 s
(measured 14-30 s of CPU: a step costs 5.5-11 us, more where many bodies are near walls),
inside the minute a user waits (``benchmarks/bench_facility.py``)."""

DEFAULT_WALL_CAP = 50.0
"""Wall-clock safety cap [s] of a plan at the default budget: a search that finds nothing is
given up after its counted work (about 20 s of CPU on a laptop core, 14-30 s measured) and, on a
machine too loaded to do that work within 50 s, by this cap (the result then says it was cut by
the clock). With the co-simulation after it, a run at the defaults stays within a minute."""

OMPL_DEFAULT_SECONDS = 1.0
"""The OMPL planners' budget [s] when no ``time_budget`` is given."""

STEP_SECONDS = (4.5e-6, 0.6e-6)
"""CPU seconds of the whole-train search per simulated control step: a constant and a part per
body (measured on the T-junction K-turn: 5.5 us a step with one trailer, 6.6 us with three,
7.5 us with five, the rollouts' checks and the search's own work included)."""


def default_steps(n: int) -> int:
    """Simulated control steps [-] of the default budget for a train of ``n`` trailers: about
    :data:`DEFAULT_SEARCH_SECONDS` of CPU (3.4 million steps for n = 1, 2.9 million for 3,
    1.8 million for 10)."""
    base, body = STEP_SECONDS
    return int(round(DEFAULT_SEARCH_SECONDS / (base + body * (int(n) + 1))))


def steps_for(seconds: float) -> int:
    """Simulated control steps [-] of a ``lattice`` budget of ``seconds`` [s] (at least 1)."""
    return max(1, int(round(seconds * STEPS_PER_SECOND)))


def checks_for(seconds: float, planner: str = "rrtconnect") -> int:
    """Motion checks [-] of a budget of ``seconds`` [s] for ``planner`` (at least 1)."""
    return max(1, int(round(seconds * CHECKS_PER_SECOND[planner])))


@dataclass
class Work:
    """Work done by one plan() call and its wall-clock safety cap.

    Parameters
    ----------
    used : int
        Motion checks done so far (the whole-train checks included, converted).
    deadline : float
        ``time.perf_counter()`` value [s] at which every search stops (the safety cap).
    capped : bool
        Set when the safety cap stopped a search.
    """

    used: int = 0
    deadline: float = math.inf
    capped: bool = False

    def done(self, limit: int) -> bool:
        """True once ``used`` reaches ``limit``, or (setting :attr:`capped`) the cap has passed."""
        if self.used >= limit:
            return True
        if time.perf_counter() >= self.deadline:
            if not self.capped:
                log.warning("planning stopped by its wall-clock safety cap after %d motion "
                            "checks: the result depends on the machine's speed", self.used)
            self.capped = True
            return True
        return False
