"""pushtrain's exceptions, all in one place.

Every exception is a :class:`PushtrainError`. Bad input (a scenario field, a map, an option, a
path, an argument) is an :class:`InputError`, which is also a :class:`ValueError`: its message
names the value and what is allowed, and the CLI turns it into exit code 2. Run-time failures (a
plan the search cannot find, an FMU that fails, a compiler that fails) are not ``ValueError``\\ s;
the CLI turns them into exit code 1. A :class:`PlanningError` that is the scenario's fault (a
start or goal in collision, a goal no way of the train's width reaches: ``details["impossible"]``)
is exit code 2 too.

::

    PushtrainError
    ├── InputError (ValueError)
    │   ├── FieldErrors                every problem of one file, each (where, value, allowed)
    │   │   ├── ScenarioError
    │   │   ├── SweepError
    │   │   └── MapError               a map file (occupancy grid YAML/image, DXF floor plan)
    │   ├── ReferencePathError         a line/arc reference that cannot be tracked
    │   ├── ControllerError, SensorError, AnalysisError, PlotError
    │   ├── PlanningInputError         (also a PlanningError)
    │   ├── CosimInputError            (also a CosimError)
    │   └── FmuInputError              (also an FmuBuildError)
    ├── PlanningError (RuntimeError)   ``reason`` is one of :data:`PLANNING_REASONS`
    ├── CosimError (RuntimeError)      the co-simulation cannot go on (an FMU error)
    └── FmuBuildError (RuntimeError)   the compiler or the packaging failed
"""

from __future__ import annotations

__all__ = [
    "PushtrainError", "InputError", "FieldErrors", "ScenarioError", "SweepError", "MapError",
    "ReferencePathError", "ControllerError", "SensorError", "AnalysisError", "PlotError",
    "PLANNING_REASONS", "PlanningError", "PlanningInputError", "CosimError", "CosimInputError",
    "FmuBuildError", "FmuInputError",
]


class PushtrainError(Exception):
    """Base of every exception pushtrain raises on purpose."""


class InputError(PushtrainError, ValueError):
    """Bad input: the message names the value and what is allowed."""


class FieldErrors(InputError):
    """Bad input in a file: ``errors`` lists (where, value, what is allowed), all reported at once.

    Raised with ``source=""`` inside a pydantic validator to report several problems at once;
    :func:`pushtrain.validation.field_errors` unpacks them.
    """

    def __init__(self, source: str, errors: list[tuple[str, object, str]]):
        self.source = source
        self.errors = list(errors)
        if source:
            lines = [f"{source}: {len(self.errors)} problem(s)"]
            lines += [f"  {where} = {value!r}: {allowed}" for where, value, allowed in self.errors]
            text = "\n".join(lines)
        else:
            text = "; ".join(
                f"{where} = {value!r}: {allowed}" for where, value, allowed in self.errors
            )
        super().__init__(text)


class ScenarioError(FieldErrors):
    """A scenario file that cannot be used; ``errors`` lists (path, value, what is allowed)."""


class SweepError(FieldErrors):
    """A sweep that cannot be run; ``errors`` lists (where, value, what is allowed)."""


class MapError(FieldErrors):
    """A map file that cannot be used (a map_server YAML or its image, a DXF floor plan);
    ``source`` is the file, ``errors`` lists (field, value, what is allowed)."""


class ReferencePathError(InputError):
    """A reference that cannot be tracked (bad segment, jump, non-finite value)."""


class ControllerError(InputError):
    """Invalid controller configuration or input (gain, limit, shape, non-finite value)."""


class SensorError(InputError):
    """Invalid sensor configuration or call (negative std, wrong joint index, bad shape)."""


class AnalysisError(InputError):
    """Invalid input to an analysis function (non-finite value, bad shape, link <= 0)."""


class PlotError(InputError):
    """Arguments that cannot be plotted (missing columns, bad sizes, bad file name)."""


PLANNING_REASONS = (
    "start_in_collision",
    "goal_in_collision",
    "no_free_space",
    "unreachable",
    "approximate_only",
    "train_check_failed",
    "pull_end_blocked",
    "pull_start_mismatch",
    "budget_exhausted",
    "invalid_input",
)
"""Allowed values of :attr:`PlanningError.reason`."""


class PlanningError(PushtrainError, RuntimeError):
    """Planning failed; ``reason`` says why and ``where`` says where.

    Parameters
    ----------
    reason : str
        One of :data:`PLANNING_REASONS`.
    message : str
        Human-readable explanation naming the value and what is allowed.
    where : tuple of float or None
        The pose or point (x [m], y [m][, theta [rad]]) the failure refers to, if any.
    details : dict or None
        Extra plain data (body index, arclength, joint angle, ...).
    """

    def __init__(self, reason: str, message: str, where=None, details: dict | None = None):
        if reason not in PLANNING_REASONS:
            raise ValueError(f"PlanningError reason = {reason!r}: allowed are {PLANNING_REASONS}")
        super().__init__(f"[{reason}] {message}")
        self.reason = reason
        self.message = message
        self.where = None if where is None else tuple(float(a) for a in where)
        self.details = dict(details or {})


class PlanningInputError(PlanningError, InputError):
    """Malformed input (map data, footprint, configuration): reason ``"invalid_input"``."""

    def __init__(self, message: str, where=None, details: dict | None = None):
        super().__init__("invalid_input", message, where, details)


class CosimError(PushtrainError, RuntimeError):
    """The co-simulation cannot start or continue (an FMU that fails or cannot be loaded)."""


class CosimInputError(CosimError, InputError):
    """A co-simulation set up with bad arguments (shapes, events, configurations, FMU file)."""


class FmuBuildError(PushtrainError, RuntimeError):
    """Building the FMU failed (the compiler, CMake or the packaging)."""


class FmuInputError(FmuBuildError, InputError):
    """An FMU build asked for with bad arguments (n out of range, bad options)."""


class NativeBuildError(PushtrainError, RuntimeError):
    """The compiled control law (``core/csrc``) cannot be built or loaded: no C compiler, a
    compiler that fails, or a library that does not match its Python binding."""


class NativeCacheError(NativeBuildError, InputError):
    """The compile cache folder (``PUSHTRAIN_CACHE``) cannot be made or written: bad input
    (exit 2), like the FMU cache's."""


__all__ += ["NativeBuildError", "NativeCacheError"]
