"""pushtrain: backward-motion planning and co-simulation of a robot pushing n passive trailers.

Subpackages: :mod:`pushtrain.fmu` (the TrailerTrain FMU and its builder), :mod:`pushtrain.cosim`
(chain kinematics, controller, co-simulation master), :mod:`pushtrain.planner` (OMPL Reeds-Shepp
planner) and :mod:`pushtrain.cli` (the click command line).
"""

__all__ = ["__version__"]


__version__ = "0.1.0"
