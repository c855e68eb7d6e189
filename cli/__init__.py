"""The command line's package (its modules are imported by name)."""

__all__: list[str] = []
