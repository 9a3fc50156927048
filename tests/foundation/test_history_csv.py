"""``history.csv`` is formatted once per row (issue 15): a flush formats only the rows recorded since
the previous one and rewrites the whole file atomically, with the bytes of one fresh
:func:`~pulseform.orchestrator.run.results.write_csv` of every row — also across a restart that restores
the rows from a checkpoint (numpy floats) and goes on recording."""

from __future__ import annotations

import csv
import io
import os

import numpy as np

from pulseform.orchestrator.run.history import History
from pulseform.orchestrator.run.results import write_csv


def _one_write(header, rows) -> bytes:
    """The bytes ``write_csv`` wrote before the history cached its formatted rows (its code then)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for row in rows:
        w.writerow([f"{v:.10g}" if isinstance(v, float) else v for v in row])
    return buf.getvalue().encode("utf-8")


def _row(rng: np.random.Generator, k: int) -> dict[str, float]:
    vals = [k * 1e-7, float(k), *rng.normal(0, 10.0 ** rng.integers(-12, 12, 5))]
    vals[3] = [0.0, -0.0, np.inf, -np.inf, np.nan, 1e-310, 0.1 + 0.2][k % 7]  # zeros, specials, subnormal
    names = ["time_s", "step", "dt_s", "odd_value", "x_m", "y \"quoted\", m", "é_J"]
    return dict(zip(names, vals))


def test_flushes_with_rows_between_give_the_bytes_of_one_fresh_write(tmp_path):
    rng = np.random.default_rng(5)
    h = History(tmp_path / "history.csv")
    h.flush()  # nothing recorded: no file
    assert not h.path.exists()
    for n in (1, 0, 3, 40, 0, 7):
        for _ in range(n):
            h.record(_row(rng, len(h.rows)))
        h.flush()
        write_csv(tmp_path / "fresh.csv", h.columns, h.rows)
        assert h.path.read_bytes() == (tmp_path / "fresh.csv").read_bytes() == _one_write(h.columns, h.rows)
        a, ref = h.array(), np.array(h.rows)  # the checkpoint's copy of the rows
        assert a.shape == ref.shape and a.dtype == ref.dtype and a.tobytes() == ref.tobytes()
    assert History.read(h.path).columns == h.columns
    assert [f for f in os.listdir(tmp_path) if f.endswith(".tmp")] == []


def test_restored_rows_and_resume_give_the_bytes_of_one_fresh_write(tmp_path):
    """As Driver.checkpoint / Driver.restore: the rows go through a numpy array (History.array) and come back as
    numpy floats; the history replaced on restore is formatted anew, then continues."""
    rng = np.random.default_rng(6)
    h = History(tmp_path / "history.csv")
    for k in range(25):
        h.record(_row(rng, k))
    h.flush()
    saved, columns = h.array(), list(h.columns)
    for k in range(25, 30):  # recorded after the checkpoint, lost with the run
        h.record(_row(rng, k))
    h.flush()

    resumed = History(tmp_path / "history.csv")
    resumed.columns = columns
    resumed.rows = [list(r) for r in saved]
    for k in range(25, 60):
        resumed.record(_row(rng, k))
        if k % 9 == 0:
            resumed.flush()
    resumed.flush()
    all_rows = [list(r) for r in saved] + resumed.rows[25:]
    assert resumed.path.read_bytes() == _one_write(columns, all_rows)
    assert resumed.array().tobytes() == np.array(all_rows).tobytes()
    # rows replaced wholesale (e.g. a history read back) are formatted anew
    resumed.rows = resumed.rows[:10]
    resumed.flush()
    assert resumed.path.read_bytes() == _one_write(columns, resumed.rows)
    assert resumed.array().tobytes() == np.array(resumed.rows).tobytes()
