"""The TrailerTrain Co-Simulation FMU (FMI 2.0 for one n, FMI 3.0 for every n): C sources
(``src/``), variable table and builder (:mod:`.build`); and the BackwardController FMU (FMI 2.0):
pushtrain's control law with its FMI glue (``controller_src/``), built by the same builder
(:mod:`.controller`)."""

__all__: list[str] = []
