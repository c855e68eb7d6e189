"""Task functions that the sweep's tests send to the workers of a Dask test cluster.

They live here, not in the test module: a worker unpickles a function by its module's name, and
pytest imports test modules from their paths (importlib mode), under names no worker can import;
this module is on the path of the tests and of the workers they spawn (pyproject's pythonpath).
"""

import os

from pushtrain.studies.sweep_task import run_task

INJECTED = "injected failure of the co-simulation"


def install_failing_runner(settle_time: float) -> None:
    """Make every run with ``sim.settle_time == settle_time`` raise, in this process (a worker
    of the test cluster or the test itself); :func:`restore_runner` undoes it."""
    from pushtrain.mission import runner

    real = getattr(runner, "_real_run_scenario", runner.run_scenario)
    runner._real_run_scenario = real

    def run_scenario(sc, *args, **kwargs):
        if sc.sim.settle_time == settle_time:
            raise RuntimeError(INJECTED)
        return real(sc, *args, **kwargs)

    runner.run_scenario = run_scenario


def restore_runner() -> None:
    from pushtrain.mission import runner

    if hasattr(runner, "_real_run_scenario"):
        runner.run_scenario = runner._real_run_scenario
        del runner._real_run_scenario


def die_when_asked(payload, shared):
    """Task function whose worker process dies (as on a crash inside the FMU) when asked."""
    if payload.get("die"):
        os._exit(3)
    return run_task(payload, shared)
