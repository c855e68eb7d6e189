"""The co-simulation's recorder: one row of named float columns per communication point.

Columns are declared once, in blocks of columns written together (the FMU's outputs, the inputs,
the reference sample, ...); callers :meth:`~Recorder.append` a row by block name, never by column
offset. Storage grows by doubling and is trimmed at the end, so a horizon much longer than the run
costs nothing (``horizon = 1e9`` s asked a preallocating recorder for 1.46 TiB).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pushtrain.errors import CosimInputError

__all__ = ["Recorder"]


class Recorder:
    """Rows of named float columns, written block by block, returned as a structured array.

    Parameters
    ----------
    blocks : sequence of (str, sequence of str)
        Block name and the names of its columns, in the order its values come in.
    order : sequence of str, optional
        The result's columns in order; every column of the blocks exactly once (default: the
        blocks' columns in order).
    capacity : int
        Rows allocated at first (>= 1); full storage doubles.
    """

    def __init__(self, blocks: Sequence[tuple[str, Sequence[str]]],
                 order: Sequence[str] | None = None, capacity: int = 1024):
        self._where: dict[str, tuple[str, int]] = {}
        for block, columns in blocks:
            for j, column in enumerate(columns):
                if column in self._where:
                    raise CosimInputError(f"column {column!r} is declared twice")
                self._where[column] = (block, j)
        self.columns = list(self._where if order is None else order)
        if sorted(self.columns) != sorted(self._where):
            missing = set(self._where) - set(self.columns)
            unknown = [c for c in self.columns if c not in self._where]
            raise CosimInputError(f"order must list every column once: missing {sorted(missing)}, "
                             f"unknown {unknown}, {len(self.columns)} given")
        self._capacity = max(1, int(capacity))
        self._store = {block: np.full((self._capacity, len(columns)), np.nan)
                       for block, columns in blocks}
        self.rows = 0

    def append(self, **values) -> None:
        """Add a row: each keyword is a block with its values (as many as its columns, or one
        value for a one-column block); columns of blocks not given stay NaN."""
        k = self.rows
        if k == self._capacity:
            self._grow()
        store = self._store
        for block, value in values.items():
            store[block][k] = value
        self.rows = k + 1

    def _grow(self) -> None:
        self._capacity *= 2
        for block, old in self._store.items():
            new = np.full((self._capacity, old.shape[1]), np.nan)
            new[: old.shape[0]] = old
            self._store[block] = new

    def column(self, name: str) -> np.ndarray:
        """The recorded values of column ``name`` (a view, rows so far)."""
        block, j = self._where[name]
        return self._store[block][: self.rows, j]

    def last(self, name: str) -> float:
        """Column ``name`` in the last row."""
        if not self.rows:
            raise IndexError("nothing recorded yet")
        block, j = self._where[name]
        return float(self._store[block][self.rows - 1, j])

    def to_array(self) -> np.ndarray:
        """The rows so far as a structured array of float64 columns in :attr:`columns` order."""
        data = np.empty(self.rows, dtype=[(name, "f8") for name in self.columns])
        for name in self.columns:
            data[name] = self.column(name)
        return data
