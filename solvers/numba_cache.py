"""Where numba keeps pulseform's compiled functions: one cache folder per version of the compiled
sources, so that a changed source can never run with stale machine code.

numba's on-disk cache (``cache=True``) is keyed on the file of each cached function only: a cached
caller in an unchanged file keeps the callee it was compiled with after the callee's file changed
(an update of pulseform, a local edit). The result is old code running on new data layouts — wrong
results or a crash. Here every module of the package that uses numba is hashed (their contents),
and numba's cache folder is ``$XDG_CACHE_HOME/pulseform/numba/<hash>`` (``~/.cache`` by default):
any change to any of them starts a fresh cache. A few older folders are kept (several checkouts),
older unused ones removed. A user's ``NUMBA_CACHE_DIR`` is respected; if the folder cannot be
made, numba's default (``__pycache__`` beside the sources) stays.

Must run before any module with ``@numba.njit(cache=True)`` is imported: ``pulseform.solvers``'s
``__init__`` calls :func:`configure`, and the orchestrator package imports ``pulseform.solvers``
first (numba itself is not imported here).
"""
from __future__ import annotations

import hashlib
import logging
import os
import shutil
import sys
import time
from pathlib import Path

__all__ = ["configure", "source_hash", "warm_up", "KEEP", "STALE_S"]

log = logging.getLogger(__name__)

#: cache folders kept besides the current one (the most recently used); older ones are removed
#: once unused for ``STALE_S`` (a process of another checkout may still be using one)
KEEP = 3
STALE_S = 86400.0
_PACKAGES = ("solvers", "orchestrator")
_MARK = "PULSEFORM_NUMBA_CACHE_DIR"  # set with NUMBA_CACHE_DIR: ours (a parent's), not the user's


def source_hash(root: Path) -> str:
    """SHA-256 (first 16 hex digits) of every ``.py`` file under ``root/solvers`` and
    ``root/orchestrator`` that mentions numba, in sorted path order."""
    h = hashlib.sha256()
    for pkg in _PACKAGES:
        for path in sorted((root / pkg).rglob("*.py")):
            data = path.read_bytes()
            if b"numba" in data:
                h.update(str(path.relative_to(root)).encode() + b"\0" + data + b"\0")
    return h.hexdigest()[:16]


def _prune(base: Path, current: Path) -> None:
    """Remove the cache folders under ``base`` (ours only) beyond the ``KEEP`` most recently used
    ones that have not been used for ``STALE_S``."""
    old = [p for p in base.iterdir() if p.is_dir() and p != current and len(p.name) == 16]
    old.sort(key=lambda p: p.stat().st_mtime, reverse=True)
    now = time.time()
    for p in old[KEEP:]:
        if now - p.stat().st_mtime > STALE_S:
            shutil.rmtree(p, ignore_errors=True)


def configure(root: Path | None = None) -> Path | None:
    """Point numba's cache at the folder of the current sources (``NUMBA_CACHE_DIR`` in the
    environment, read by numba when it is imported, and ``numba.config.CACHE_DIR`` if it already
    is); returns the folder, or None where numba's default stays: ``NUMBA_CACHE_DIR`` set by the
    user, or no writable cache home."""
    env = os.environ.get("NUMBA_CACHE_DIR")
    if env and env != os.environ.get(_MARK):
        return None
    root = Path(__file__).resolve().parents[1] if root is None else Path(root)
    home = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    base = home / "pulseform" / "numba"
    folder = base / source_hash(root)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        os.utime(folder)                       # most recently used
        _prune(base, folder)
    except OSError as exc:
        log.debug("numba cache: %s not usable (%s); numba's default cache", folder, exc)
        return None
    os.environ["NUMBA_CACHE_DIR"] = os.environ[_MARK] = str(folder)
    numba = sys.modules.get("numba")
    if numba is not None:
        numba.config.CACHE_DIR = str(folder)
    return folder


def warm_up() -> float:
    """numba's one-time set-up of its compiler targets (the typing and code-generation registries,
    ~0.2-0.4 s, otherwise paid by the first compiled function a process loads from the cache), done by
    compiling a trivial function; a process that forks workers (``orchestrator/run/warm.py``) calls it
    once so that its children do not. Returns the seconds it took."""
    t0 = time.perf_counter()
    import numba

    numba.njit(lambda x: x + 1.0)(1.0)
    return time.perf_counter() - t0
