"""Pictures of runs: maps, time series and the train animation.

:func:`~.plots.plot_all` writes a run's standard pictures; each figure is imported from the
module of its concern, :mod:`.mapview`, :mod:`.timeseries` or :mod:`.animation`, which stand on
:mod:`.common` and :mod:`.geometry`.

Importing this package imports nothing else (no matplotlib): code that only names the files of
a run (the CLI's main process) takes the names from here.
"""

__all__ = ["PNG_FILES", "GIF_FILE", "HTML_FILE"]


PNG_FILES = ("map.png", "inputs_joints.png", "tracking_error.png", "lateral_forces.png")
"""The standard plots of a run, as :func:`~.plots.plot_file` names them."""
GIF_FILE = "train.gif"
"""The standard animation of a run."""
HTML_FILE = "report.html"
"""The run's page to open in a browser (:mod:`.html`)."""
