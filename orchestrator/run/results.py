"""The results folder of one run, written atomically (temp file + rename).

Layout::

    <out>/case.toml      the resolved case (defaults filled in, overrides applied)
    <out>/metrics.json   flat dict of named scalars, unit in the key name
    <out>/history.csv    time series, one row per recorded step
    <out>/fields/        XDMF/HDF5 fields for ParaView
    <out>/plots/*.png    figures
    <out>/run.log        the run's log
    <out>/.pulseform     marker: this folder was made by pulseform (what ``--force`` may replace)

A folder in use is locked (``flock`` on the folder itself, released by the kernel when the process
ends, so a dead run leaves no stale lock): a second run on it is refused while the first is alive.
Files are created with the user's umask.
"""

from __future__ import annotations

import csv
import errno
import fcntl
import io
import json
import math
import os
import shutil
import socket
import tempfile
import time
from pathlib import Path
from typing import Any, Iterable, Sequence

from .. import __version__


class ResultsExistError(FileExistsError):
    """The results folder exists and neither ``--force`` nor ``--resume`` was given, or it cannot be
    replaced (not made by pulseform, or in use by a running pulseform)."""


#: the file that marks a folder as made by pulseform
MARKER_NAME = ".pulseform"

#: errno values of a full disk / quota / file-size limit
DISK_FULL_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder and ``os.replace``."""
    atomic_write_chunks(path, (data,))


def atomic_write_chunks(path: Path, chunks: Iterable[bytes]) -> None:
    """Write the concatenation of ``chunks`` to ``path`` atomically (temporary file in the same
    folder, ``fsync``, ``os.replace``), without joining them into one buffer first."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp makes 0600: give the file the user's umask
        with os.fdopen(fd, "wb") as fh:
            fh.writelines(chunks)
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


def read_metrics(path: Path) -> dict[str, float]:
    """The numbers of a ``metrics.json`` (null and the ``status`` text left out)."""
    data = json.loads(Path(path).read_text())
    return {k: float(v) for k, v in data.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}


def csv_lines(rows: Iterable[Sequence[float]]) -> str:
    """CSV text of ``rows`` as :func:`write_csv` writes them (floats with 10 significant digits,
    ``csv`` writer quoting, one ``\\n``-terminated line per row)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    for row in rows:
        w.writerow([f"{v:.10g}" if isinstance(v, float) else v for v in row])
    return buf.getvalue()


def write_csv(path: Path, header: Sequence[str], rows: Iterable[Sequence[float]]) -> None:
    """Write a CSV table atomically (numbers with 10 significant digits)."""
    atomic_write_text(path, csv_lines([header]) + csv_lines(rows))


def _lock_folder(root: Path) -> int:
    """An exclusive ``flock`` on the folder ``root``: its descriptor (closing it releases the lock).
    Raises :class:`ResultsExistError` while another process holds it."""
    fd = os.open(root, os.O_RDONLY | os.O_DIRECTORY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        try:
            who = json.loads((Path(root) / MARKER_NAME).read_text()).get("pid", "?")
        except (OSError, ValueError, AttributeError):
            who = "?"
        raise ResultsExistError(f"{root}: in use by a running pulseform (process {who}); wait for it to end or "
                                "choose another --out") from None
    return fd


def refuse_if_in_use(root: Path) -> None:
    """Raise :class:`ResultsExistError` if a running pulseform holds the folder ``root`` (see
    :class:`ResultsFolder`); a missing folder is not in use."""
    if Path(root).is_dir():
        os.close(_lock_folder(Path(root)))


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

    def __init__(self, root: Path, *, force: bool = False, resume: bool = False, lock: bool = True) -> None:
        self.root = Path(root)
        self._lock_fd: int | None = None
        try:
            os.stat(self.root)
        except FileNotFoundError:
            pass
        except OSError as exc:  # a name too long, a file in the path, no permission
            shown = str(self.root) if len(str(self.root)) <= 120 else str(self.root)[:120] + "…"
            raise ResultsExistError(f"{shown}: cannot be a results folder ({exc.strerror}); choose another --out") \
                from None
        if self.root.exists() and not self.root.is_dir():
            raise ResultsExistError(f"{self.root}: exists and is not a folder; choose another --out")
        if self.root.is_dir() and lock:
            self._lock()
        try:
            if self.root.is_dir() and any(self.root.iterdir()):
                if resume:
                    pass
                elif force:
                    self._empty_for_force()
                else:
                    raise ResultsExistError(f"{self.root}: results folder exists; use --force to replace it or "
                                            "--resume to continue")
            self.root.mkdir(parents=True, exist_ok=True)
            if lock and self._lock_fd is None:
                self._lock()
            self._write_marker()
            self.fields.mkdir(exist_ok=True)
            self.plots.mkdir(exist_ok=True)
        except OSError as exc:
            self.release()
            if isinstance(exc, ResultsExistError):
                raise
            raise ResultsExistError(f"{self.root}: cannot create the results folder ({exc.strerror})") from None
        except BaseException:
            self.release()
            raise

    def _lock(self) -> None:
        """Lock the folder for this process (refused while another pulseform holds it)."""
        self._lock_fd = _lock_folder(self.root)

    def release(self) -> None:
        """Release the folder's lock (also released by the kernel when the process ends)."""
        if self._lock_fd is not None:
            os.close(self._lock_fd)
            self._lock_fd = None

    def _write_marker(self) -> None:
        atomic_write_text(self.root / MARKER_NAME, json.dumps(
            {"made_by": f"pulseform {__version__}", "pid": os.getpid(), "host": socket.gethostname(),
             "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}) + "\n")

    def _empty_for_force(self) -> None:
        """``--force``: empty a folder pulseform made; refuse any other folder."""
        if not (self.root / MARKER_NAME).is_file():
            raise ResultsExistError(f"{self.root}: not a results folder made by pulseform (no {MARKER_NAME} "
                                    "marker); --force replaces only those: choose another --out")
        for child in self.root.iterdir():
            if child.is_dir() and not child.is_symlink():
                shutil.rmtree(child)
            else:
                child.unlink()

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
