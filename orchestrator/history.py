"""Time-series recorder behind ``history.csv``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .results import write_csv


class History:
    """Rows of named scalars over time, flushed atomically to a CSV file.

    The column set is fixed by the first row; later rows must have the same keys.
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.columns: list[str] = []
        self.rows: list[list[float]] = []

    def record(self, row: dict[str, float]) -> None:
        """Append one row (a dict of column name -> value, SI units in the names)."""
        if not self.columns:
            self.columns = list(row)
        elif list(row) != self.columns:
            raise ValueError(f"history row keys changed: {sorted(set(row) ^ set(self.columns))}")
        self.rows.append([float(row[c]) for c in self.columns])

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
        j = self.columns.index(name)
        return np.array([r[j] for r in self.rows])

    def flush(self) -> None:
        """Rewrite the CSV atomically with every row so far."""
        if self.columns:
            write_csv(self.path, self.columns, self.rows)
