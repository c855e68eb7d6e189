"""The co-simulation's recorder: one row of named float columns per communication point.

Columns are declared once, in blocks of columns written together (the FMU's outputs, the inputs,
the reference sample, ...), so no caller computes offsets into a flat row. Two ways to record:

* :meth:`~Recorder.append` a row by block name (blocks not given stay NaN);
* fill the blocks of the preallocated :attr:`~Recorder.row` through :meth:`~Recorder.view` (an
  FMU reader can write into its view directly) and :meth:`~Recorder.commit` it: one copy of one
  row per step. Values not rewritten are kept from the row before;
* write whole rows straight into the storage (:meth:`~Recorder.free_rows`, at the offsets of
  :meth:`~Recorder.block_start`) and :meth:`~Recorder.advance`: the master's step loop.

Storage is one float array (one row per point, the blocks side by side) that grows by doubling
and is trimmed at the end, so a horizon much longer than the run costs nothing
(``horizon = 1e9`` s asked a preallocating recorder for 1.46 TiB).
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
        self._where: dict[str, int] = {}  # column -> its index in a row
        self._spans: dict[str, slice] = {}  # block -> its columns in a row
        for block, columns in blocks:
            start = len(self._where)
            for column in columns:
                if column in self._where:
                    raise CosimInputError(f"column {column!r} is declared twice")
                self._where[column] = len(self._where)
            self._spans[block] = slice(start, len(self._where))
        self.columns = list(self._where if order is None else order)
        if sorted(self.columns) != sorted(self._where):
            missing = set(self._where) - set(self.columns)
            unknown = [c for c in self.columns if c not in self._where]
            raise CosimInputError(f"order must list every column once: missing {sorted(missing)}, "
                                  f"unknown {unknown}, {len(self.columns)} given")
        self._runs = _runs([self._where[c] for c in self.columns])
        self._dtype = np.dtype([(name, "f8") for name in self.columns])
        self._capacity = max(1, int(capacity))
        self._store = np.empty((self._capacity, len(self._where)))  # rows < self.rows are set
        self.row = np.full(len(self._where), np.nan)
        """The row the next :meth:`commit` records (its blocks through :meth:`view`)."""
        self.rows = 0

    def view(self, block: str) -> np.ndarray:
        """The columns of ``block`` in :attr:`row` (a writable, contiguous view)."""
        return self.row[self._spans[block]]

    def commit(self) -> None:
        """Record :attr:`row` as the next row (one copy); the row keeps its values."""
        k = self.rows
        if k == self._capacity:
            self._grow()
        self._store[k] = self.row
        self.rows = k + 1

    def free_rows(self) -> np.ndarray:
        """The storage's rows after the recorded ones (at least one: full storage grows), for
        a writer that fills several rows at once (the master's step loop) and then
        :meth:`advance` them; a view, valid until the next :meth:`commit` or :meth:`advance`."""
        if self.rows == self._capacity:
            self._grow()
        return self._store[self.rows:]

    def advance(self, count: int) -> None:
        """Record the first ``count`` rows of :meth:`free_rows` as written; :attr:`row` becomes
        the last of them."""
        if not 0 <= count <= self._capacity - self.rows:
            raise ValueError(f"advance({count}): {self._capacity - self.rows} rows are free")
        self.rows += count
        if count:
            self.row[:] = self._store[self.rows - 1]

    def index(self, column: str) -> int:
        """Index in a row of ``column``."""
        return self._where[column]

    def has(self, block: str) -> bool:
        """Whether ``block`` is one of the recorder's blocks."""
        return block in self._spans

    def block_start(self, block: str) -> int:
        """Index in a row of the first column of ``block``."""
        return self._spans[block].start

    def append(self, **values) -> None:
        """Add a row: each keyword is a block with its values (as many as its columns, or one
        value for a one-column block); columns of blocks not given stay NaN."""
        row, spans = self.row, self._spans
        row.fill(np.nan)
        for block, value in values.items():
            row[spans[block]] = value
        self.commit()

    def _grow(self) -> None:
        self._capacity *= 2
        new = np.empty((self._capacity, self._store.shape[1]))
        new[: self.rows] = self._store[: self.rows]
        self._store = new

    def column(self, name: str) -> np.ndarray:
        """The recorded values of column ``name`` (a view, rows so far)."""
        return self._store[: self.rows, self._where[name]]

    def last(self, name: str) -> float:
        """Column ``name`` in the last row."""
        if not self.rows:
            raise IndexError("nothing recorded yet")
        return float(self._store[self.rows - 1, self._where[name]])

    def to_array(self) -> np.ndarray:
        """The rows so far as a structured array of float64 columns in :attr:`columns` order.

        If the blocks lie in that order, the array is the storage's first rows (no copy; rows
        recorded later do not change it), else a copy."""
        rows = self.rows
        if self._runs == [(0, 0, self._store.shape[1])]:
            return self._store[:rows].view(self._dtype).reshape(rows)
        table = np.empty((rows, self._store.shape[1]))
        for to, start, count in self._runs:  # a few block copies, not a gather per element
            table[:, to:to + count] = self._store[:rows, start:start + count]
        return table.view(self._dtype).reshape(rows)


def _runs(where: list[int]) -> list[tuple[int, int, int]]:
    """``(first result column, first row index, count)`` of each run of result columns that sit
    side by side in a row too (``where[j]``: row index of result column j)."""
    runs: list[tuple[int, int, int]] = []
    for j, k in enumerate(where):
        if runs and runs[-1][1] + runs[-1][2] == k:
            to, start, count = runs[-1]
            runs[-1] = (to, start, count + 1)
        else:
            runs.append((j, k, 1))
    return runs
