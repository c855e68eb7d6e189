"""The co-simulation: the master that steps the TrailerTrain FMU with the controller in the loop
(:mod:`.master`), the FMU wrapper (:mod:`.fmu_slave`) and the sensor model (:mod:`.sensors`).

The train model and the control law live in :mod:`pushtrain.core`.
"""

__all__: list[str] = []
