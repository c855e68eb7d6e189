"""What the commands share: exit codes, the bad-input exception and loading a scenario."""

from __future__ import annotations

import logging

import click

from pushtrain.mission.scenario import Scenario, ScenarioError, load_scenario, parse_scenario

EXIT_OK, EXIT_NOT_REACHED, EXIT_BAD_INPUT = 0, 1, 2
_INPUT_REASONS = {"start_in_collision", "goal_in_collision", "no_free_space", "bad_input"}

log = logging.getLogger("pushtrain")


class BadInput(click.ClickException):
    exit_code = EXIT_BAD_INPUT


def _scenario(path: str, trailers: int | None = None, seed: int | None = None) -> Scenario:
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
