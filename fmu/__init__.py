"""The TrailerTrain Co-Simulation FMU (FMI 2.0 for one n, FMI 3.0 for every n): C sources
(``src/``), variable table and builder; and the BackwardController FMU (FMI 2.0): pushtrain's
control law with its FMI glue (``controller_src/``), built by the same builder."""

from .build import FmuBuildError, build_fmu, cache_dir, render_model_description
from .controller import ControllerTable, TableSegment, build_controller_fmu

__all__ = ["ControllerTable", "FmuBuildError", "TableSegment", "build_controller_fmu",
           "build_fmu", "cache_dir", "render_model_description"]
