"""Old import paths kept for one release: each old module becomes an alias of its new home."""

from __future__ import annotations

import importlib
import sys
import warnings

__all__ = ["MOVED_MODULES", "alias_module"]

MOVED_MODULES = {
    "pushtrain.cosim.kinematics": "pushtrain.core.kinematics",
    "pushtrain.cosim.reference": "pushtrain.core.reference",
    "pushtrain.cosim.controller": "pushtrain.core.controller",
    "pushtrain.cosim.pulling": "pushtrain.core.pulling",
    "pushtrain.cosim.governor": "pushtrain.core.governor",
    "pushtrain.cosim.openloop": "pushtrain.core.openloop",
    "pushtrain.cosim.analysis": "pushtrain.core.analysis",
    "pushtrain.cosim.sweep": "pushtrain.studies.sweep",
    "pushtrain.cosim.sweep_report": "pushtrain.studies.sweep_report",
    "pushtrain.cosim.slipstudy": "pushtrain.studies.slipstudy",
    "pushtrain.cosim.plots": "pushtrain.report.plots",
    "pushtrain.cli.scenario": "pushtrain.mission.scenario",
    "pushtrain.cli.runner": "pushtrain.mission.runner",
}
"""Old module path -> new module path (version 0.2 moved them; 0.3 removes the old paths)."""


def alias_module(old: str) -> None:
    """Make ``old`` (the module being imported) the module at its new path, with a
    DeprecationWarning that names the new path."""
    new = MOVED_MODULES[old]
    warnings.warn(f"{old} moved to {new}; the old path is deprecated and goes away in "
                  "pushtrain 0.3", DeprecationWarning, stacklevel=3)
    sys.modules[old] = importlib.import_module(new)
