"""pushtrain: backward-motion planning and co-simulation of a robot pushing n passive trailers.

Subpackages (rooms; the README's "Architecture: who imports whom" gives the arrows):
:mod:`pushtrain.core` (train model and control law), :mod:`pushtrain.fmu` (the TrailerTrain FMU
and its builder), :mod:`pushtrain.facility` (the facility map), :mod:`pushtrain.planner` (the
whole-train planner), :mod:`pushtrain.cosim` (the co-simulation master), :mod:`pushtrain.report`
(plots and pages), :mod:`pushtrain.mission` (scenarios and their runner),
:mod:`pushtrain.studies` (sweeps, the slip study) and :mod:`pushtrain.cli` (the command line).
This package itself holds what every room may use: errors, file writing, validation, limits.
"""

__all__ = ["__version__"]

__version__ = "0.1.0"
