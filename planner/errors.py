"""Errors raised by :mod:`pushtrain.planner`."""

from __future__ import annotations

__all__ = ["PlanningError", "PlanningInputError", "REASONS"]

REASONS = (
    "start_in_collision",
    "goal_in_collision",
    "no_free_space",
    "unreachable",
    "approximate_only",
    "train_check_failed",
    "pull_end_blocked",
    "pull_start_mismatch",
    "invalid_input",
)
"""Allowed values of :attr:`PlanningError.reason`."""


class PlanningError(RuntimeError):
    """Planning failed; ``reason`` says why and ``where`` says where.

    Parameters
    ----------
    reason : str
        One of :data:`REASONS`.
    message : str
        Human-readable explanation naming the value and what is allowed.
    where : tuple of float or None
        The pose or point (x [m], y [m][, theta [rad]]) the failure refers to, if any.
    details : dict or None
        Extra plain data (body index, arclength, joint angle, ...).
    """

    def __init__(self, reason: str, message: str, where=None, details: dict | None = None):
        if reason not in REASONS:
            raise ValueError(f"PlanningError reason = {reason!r}: allowed are {REASONS}")
        super().__init__(f"[{reason}] {message}")
        self.reason = reason
        self.where = None if where is None else tuple(float(a) for a in where)
        self.details = dict(details or {})


class PlanningInputError(PlanningError, ValueError):
    """Malformed input (map data, footprint, configuration): reason ``"invalid_input"``."""

    def __init__(self, message: str, where=None, details: dict | None = None):
        super().__init__("invalid_input", message, where, details)
