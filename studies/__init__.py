"""Studies that run many missions: parameter sweeps (:mod:`.sweep`, built from :mod:`.sweep_spec`,
:mod:`.sweep_runs`, :mod:`.sweep_task`, :mod:`.sweep_results`; reported by :mod:`.sweep_report`)
and the pure-rotation slip study (:mod:`.slipstudy`). Only :mod:`.sweep` imports dask."""

__all__: list[str] = []
