"""Deprecated: the planner's errors live in :mod:`pushtrain.errors` (kept for one release)."""

import warnings

from pushtrain.errors import PLANNING_REASONS as REASONS  # noqa: F401
from pushtrain.errors import PlanningError, PlanningInputError  # noqa: F401

warnings.warn("pushtrain.planner.errors is deprecated: import PlanningError, PlanningInputError "
              "and PLANNING_REASONS from pushtrain.errors", DeprecationWarning, stacklevel=2)
