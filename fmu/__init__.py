"""The TrailerTrain Co-Simulation FMU (FMI 2.0 for one n, FMI 3.0 for every n): C sources
(``src/``), variable table and builder."""

from .build import FmuBuildError, build_fmu, cache_dir, render_model_description

__all__ = ["FmuBuildError", "build_fmu", "cache_dir", "render_model_description"]
