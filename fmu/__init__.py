"""The TrailerTrain FMI 2.0 Co-Simulation FMU: C sources (``src/``), variable table and builder."""

from .build import FmuBuildError, build_fmu, cache_dir, render_model_description

__all__ = ["FmuBuildError", "build_fmu", "cache_dir", "render_model_description"]
