"""The command line's exit codes (no imports: the console scripts' guard uses them before any
other module has loaded)."""

EXIT_OK = 0
"""The goal was reached, or a fixed-horizon run completed."""
EXIT_NOT_REACHED = 1
"""The run completed but did not reach the goal, no plan was found, or a plot was not drawn."""
EXIT_BAD_INPUT = 2
"""Bad input: a scenario field, a file, an option, an output folder."""
EXIT_INTERRUPTED = 130
"""Ctrl-C (128 + SIGINT, as a shell reports it); what was written so far is kept."""
