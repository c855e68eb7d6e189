"""What the commands share: exit codes, the bad-input exception, loading a scenario, turning
pushtrain's errors into exit codes, and the common arguments and options."""

from __future__ import annotations

import logging
from contextlib import contextmanager
from typing import TYPE_CHECKING

import click

from pushtrain.errors import InputError, PlanningError, PushtrainError, ScenarioError
from pushtrain.fmu.variables import MAX_TRAILERS

from .exits import EXIT_BAD_INPUT, EXIT_NOT_REACHED

if TYPE_CHECKING:  # the scenario's models (pydantic, numpy) load when a command reads one
    from pushtrain.mission.scenario import Scenario

__all__ = ["BadInput", "load_scenario_with_overrides", "check_map", "click_error", "click_errors",
           "scenario_argument", "out_dir_option", "trailers_option", "csv_option"]

# planning failures that are the scenario's fault (exit 2); the others mean no plan was found
_INPUT_REASONS = {"start_in_collision", "goal_in_collision", "no_free_space"}

log = logging.getLogger("pushtrain.cli")


class BadInput(click.ClickException):
    """Bad input: the message names the field, the value and what is allowed (exit 2)."""

    exit_code = EXIT_BAD_INPUT


def load_scenario_with_overrides(path: str, trailers: int | None = None,
                                 seed: int | None = None) -> Scenario:
    """Load the scenario at ``path`` with the command line's overrides, or raise BadInput."""
    from pushtrain.mission.scenario import load_scenario, parse_scenario

    try:
        sc = load_scenario(path)
        if trailers is not None or seed is not None:
            data = sc.model_dump()
            if trailers is not None:
                data["train"]["n"] = trailers
                for key in ("front", "rear"):
                    data["train"][key] = None
                for key in ("mass", "inertia", "payload", "mu"):
                    if isinstance(data["train"][key], list):
                        raise ScenarioError(path, [(f"train.{key}", data["train"][key],
                                                    "a single value when --trailers overrides n")])
            if seed is not None:
                data["seed"] = seed
            sc = parse_scenario(data, path)
        return sc
    except ScenarioError as exc:
        raise BadInput(str(exc)) from None


def check_map(sc: Scenario) -> None:
    """Raise BadInput when the map is malformed or the start or goal lies outside it."""
    from pushtrain.mission.runner import check_start_in_map

    try:
        check_start_in_map(sc)
    except ScenarioError as exc:
        raise BadInput(str(exc)) from None
    except ValueError as exc:  # the planner's input errors (bad polygons)
        raise BadInput(f"{sc.name}: map: {exc}") from None


def click_error(exc: PushtrainError) -> click.ClickException:
    """The click exception for one of pushtrain's errors: exit 2 for bad input (including a
    start or goal in collision), 1 for a run-time failure (no plan found, an FMU build)."""
    planning = isinstance(exc, PlanningError)
    text = f"planning failed ({exc.reason}): {exc}" if planning else str(exc)
    if isinstance(exc, InputError) or planning and exc.reason in _INPUT_REASONS:
        return BadInput(text)
    err = click.ClickException(text)
    err.exit_code = EXIT_NOT_REACHED
    return err


@contextmanager
def click_errors():
    """Turn pushtrain's errors raised inside into click exceptions (:func:`click_error`)."""
    try:
        yield
    except PushtrainError as exc:
        raise click_error(exc) from None


scenario_argument = click.argument("scenario", type=click.Path(exists=True, dir_okay=False))
out_dir_option = click.option(
    "--out", "-o", "out", type=click.Path(file_okay=False), metavar="DIR",
    help="Output folder: new, empty or a previous run's (replaced); default "
         "runs/<name>-<timestamp>/.")
trailers_option = click.option("--trailers", type=click.IntRange(1, MAX_TRAILERS), metavar="N",
                               help="Override train.n.")
csv_option = click.option("--csv", "csv", is_flag=True,
                          help="Also write results.csv (the results.npz table as text).")
plot_processes_option = click.option(
    "--plot-processes", "plot_processes", type=click.IntRange(0, 2), default=None, metavar="N",
    help="Processes that draw the plots and the GIF beside this one (0: draw here, the least "
         "memory; default: 2 on two or more cores, else 1).")

