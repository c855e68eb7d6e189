"""Studies that run many missions: parameter sweeps (:mod:`.sweep`, :mod:`.sweep_report`) and
the pure-rotation slip study (:mod:`.slipstudy`). Only the sweep imports dask."""
