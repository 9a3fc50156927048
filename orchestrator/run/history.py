"""Time-series recorder behind ``history.csv``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .results import atomic_write_chunks, csv_lines


class History:
    """Rows of named scalars over time, flushed atomically to a CSV file.

    The column set is fixed by the first row; later rows must have the same keys.

    Each row is formatted as CSV once: :meth:`flush` formats only the rows recorded since the
    previous flush and rewrites the whole file from the cached text (the same bytes as
    :func:`~.results.write_csv` of every row). Assigning :attr:`rows` or :attr:`columns` (a restart
    restoring its history) drops the cache; rows must not be changed in place once flushed. The
    checkpoint's array of the rows (:meth:`array`) is kept the same way.
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._columns: list[str] = []
        self._rows: list[list[float]] = []
        self._drop_cache()

    @property
    def columns(self) -> list[str]:
        """Column names (SI units in the names)."""
        return self._columns

    @columns.setter
    def columns(self, value: list[str]) -> None:
        self._columns = value
        self._drop_cache()

    @property
    def rows(self) -> list[list[float]]:
        """The recorded rows, in the order of :attr:`columns`."""
        return self._rows

    @rows.setter
    def rows(self, value: list[list[float]]) -> None:
        self._rows = value
        self._drop_cache()

    def _drop_cache(self) -> None:
        self._header = b""  # the CSV header line, UTF-8
        self._chunks: list[bytes] = []  # CSV text (UTF-8) of rows[:self._formatted], one chunk per flush
        self._formatted = 0
        self._blocks: list[np.ndarray] = []  # rows[:self._in_blocks] as arrays, for :meth:`array`
        self._in_blocks = 0

    def record(self, row: dict[str, float]) -> None:
        """Append one row (a dict of column name -> value, SI units in the names)."""
        if not self._columns:
            self.columns = list(row)
        elif list(row) != self._columns:
            raise ValueError(f"history row keys changed: {sorted(set(row) ^ set(self._columns))}")
        self._rows.append([float(row[c]) for c in self._columns])

    @classmethod
    def read(cls, path: Path) -> "History":
        """The rows of a ``history.csv`` written by :meth:`flush` (e.g. to draw its plots again)."""
        import csv

        h = cls(path)
        with open(path, newline="", encoding="utf-8") as fh:
            reader = csv.reader(fh)
            h.columns = next(reader, [])
            h.rows = [[float(v) for v in row] for row in reader if row]
        return h

    def column(self, name: str) -> np.ndarray:
        """One column as an array."""
        j = self._columns.index(name)
        return np.array([r[j] for r in self._rows])

    def array(self) -> np.ndarray:
        """Every row so far as one (rows, columns) float array, ``np.array(rows)`` (for the
        checkpoint; read-only); only the rows recorded since the previous call are converted."""
        if not self._rows or self._in_blocks > len(self._rows):
            self._drop_cache()
            return np.array(self._rows)
        if self._in_blocks < len(self._rows):
            block = np.concatenate([*self._blocks, np.array(self._rows[self._in_blocks:])])
            block.flags.writeable = False
            self._blocks = [block]
            self._in_blocks = len(self._rows)
        return self._blocks[0]

    def flush(self) -> None:
        """Rewrite the CSV atomically with every row so far (formatting only the rows recorded
        since the previous flush)."""
        if not self._columns:
            return
        if self._formatted > len(self._rows):  # rows were removed: format them all again
            self._drop_cache()
        if not self._header:
            self._header = csv_lines([self._columns]).encode("utf-8")
        if self._formatted < len(self._rows):
            self._chunks.append(csv_lines(self._rows[self._formatted:]).encode("utf-8"))
            self._formatted = len(self._rows)
        atomic_write_chunks(self.path, [self._header, *self._chunks])
