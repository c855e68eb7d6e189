"""Pictures of runs: maps, time series and the train animation.

:mod:`.plots` offers every figure and :func:`~.plots.plot_all`; the figures live by concern in
:mod:`.mapview`, :mod:`.timeseries` and :mod:`.animation`, on :mod:`.common` and :mod:`.geometry`.
"""
