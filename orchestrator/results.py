"""The results folder of one run, written atomically (temp file + rename).

Layout::

    <out>/case.toml      the resolved case (defaults filled in, overrides applied)
    <out>/metrics.json   flat dict of named scalars, unit in the key name
    <out>/history.csv    time series, one row per recorded step
    <out>/fields/        XDMF/HDF5 fields for ParaView
    <out>/plots/*.png    figures
    <out>/run.log        the run's log
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Iterable, Sequence


class ResultsExistError(FileExistsError):
    """The results folder exists and neither ``--force`` nor ``--resume`` was given."""


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder and ``os.replace``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def atomic_write_text(path: Path, text: str) -> None:
    """Atomic UTF-8 text write."""
    atomic_write_bytes(path, text.encode("utf-8"))


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if hasattr(value, "item"):  # numpy scalar
        return _json_safe(value.item())
    return value


def write_metrics(path: Path, metrics: dict[str, Any]) -> None:
    """Write a flat dict of named scalars as JSON (non-finite numbers become null)."""
    flat = {k: _json_safe(v) for k, v in sorted(metrics.items())}
    atomic_write_text(path, json.dumps(flat, indent=2) + "\n")


def write_csv(path: Path, header: Sequence[str], rows: Iterable[Sequence[float]]) -> None:
    """Write a CSV table atomically (numbers with 10 significant digits)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for row in rows:
        w.writerow([f"{v:.10g}" if isinstance(v, float) else v for v in row])
    atomic_write_text(path, buf.getvalue())


class ResultsFolder:
    """One run's output folder.

    Parameters
    ----------
    root : Path
        Folder to create.
    force : bool
        Replace an existing folder.
    resume : bool
        Reuse an existing folder (continue a run).
    """

    def __init__(self, root: Path, *, force: bool = False, resume: bool = False) -> None:
        self.root = Path(root)
        if self.root.exists() and not self.root.is_dir():
            raise ResultsExistError(f"{self.root}: exists and is not a folder; choose another --out")
        if self.root.exists() and any(self.root.iterdir()):
            if resume:
                pass
            elif force:
                shutil.rmtree(self.root)
            else:
                raise ResultsExistError(
                    f"{self.root}: results folder exists; use --force to replace it or --resume to continue")
        try:
            self.root.mkdir(parents=True, exist_ok=True)
            self.fields.mkdir(exist_ok=True)
            self.plots.mkdir(exist_ok=True)
        except OSError as exc:
            raise ResultsExistError(f"{self.root}: cannot create the results folder ({exc.strerror})") from None

    @property
    def fields(self) -> Path:
        """Folder of XDMF/HDF5 field files."""
        return self.root / "fields"

    @property
    def plots(self) -> Path:
        """Folder of PNG figures."""
        return self.root / "plots"

    @property
    def log_file(self) -> Path:
        """The run's log file."""
        return self.root / "run.log"

    def write_text(self, name: str, text: str) -> Path:
        """Atomically write a text file inside the folder."""
        path = self.root / name
        atomic_write_text(path, text)
        return path

    def write_metrics(self, metrics: dict[str, Any]) -> Path:
        """Atomically write ``metrics.json``."""
        path = self.root / "metrics.json"
        write_metrics(path, metrics)
        return path
