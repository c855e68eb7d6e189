"""Errors shared across subpackages."""

from __future__ import annotations

__all__ = ["FieldErrors"]


class FieldErrors(ValueError):
    """Bad input in a file: ``errors`` lists (where, value, what is allowed), all reported at once."""

    def __init__(self, source: str, errors: list[tuple[str, object, str]]):
        self.source = source
        self.errors = errors
        lines = [f"{source}: {len(errors)} problem(s)"]
        lines += [f"  {where} = {value!r}: {allowed}" for where, value, allowed in errors]
        super().__init__("\n".join(lines))
