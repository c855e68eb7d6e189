"""One module per ``pushtrain`` command; :mod:`pushtrain.cli.main` adds them to the group."""

__all__: list[str] = []
