"""getdp's files as the runner handles them: run folders discarded off the critical path, the tables
getdp prints (whole-run and per-element), the ``run.pro`` lists, element volumes of an EM mesh."""

from __future__ import annotations

import shutil
import threading
import uuid
from pathlib import Path

import numpy as np

from .mesh import EMMesh


def discard_folder(path: Path) -> threading.Thread | None:
    """Delete a run folder off the critical path: rename it, remove it in a daemon thread.

    Returns the thread (join it to wait for the deletion), or None when the folder is gone already
    or could not be renamed (then it was deleted synchronously)."""
    path = Path(path)
    if not path.exists():
        return None
    trash = path.with_name(f".trash_{path.name}_{uuid.uuid4().hex[:8]}")
    try:
        path.rename(trash)
    except OSError:
        shutil.rmtree(path, ignore_errors=True)
        return None
    thread = threading.Thread(target=shutil.rmtree, args=(trash, True), daemon=True)
    thread.start()
    return thread


def read_element_table(path: Path, ncomp: int, n_blocks: int) -> tuple[np.ndarray, np.ndarray]:
    """Read ``n_blocks`` appended getdp ElementTable blocks (count, then "id v1 .. vncomp" rows).

    Returns (element ids of the first block, values (n_blocks, count, ncomp)); every block
    must list the same elements in the same order.
    """
    tok = np.fromstring(Path(path).read_text(), sep=" ")   # C parser, accepts nan/inf
    pos, ids, blocks = 0, None, []
    for _ in range(n_blocks):
        if pos >= tok.size:
            raise RuntimeError(f"{path}: fewer than {n_blocks} element blocks")
        count = int(tok[pos])
        rows = tok[pos + 1: pos + 1 + count * (1 + ncomp)].reshape(count, 1 + ncomp)
        pos += 1 + count * (1 + ncomp)
        if ids is None:
            ids = rows[:, 0].astype(np.int64)
        elif not np.array_equal(rows[:, 0].astype(np.int64), ids):
            raise RuntimeError(f"{path}: element order changed between sub-steps")
        blocks.append(rows[:, 1:])
    if pos != tok.size:
        raise RuntimeError(f"{path}: unexpected trailing data")
    return ids, np.stack(blocks)


def init_list_line(name: str, ids, values) -> str:
    """A ``run.pro`` line defining the list ``name() = {N, id, value, ...}`` for ``ValueFromIndex``
    (the pair count first, else every lookup silently returns 0); values in ``repr``: exact round trip."""
    pairs = [f"{int(i)}, {float(v)!r}" for i, v in zip(np.asarray(ids).tolist(), np.asarray(values).tolist())]
    body = ",\n  ".join(", ".join(pairs[j:j + 8]) for j in range(0, len(pairs), 8))
    return f"{name}() = {{{len(pairs)},\n  {body}}};"


def read_table(path: Path) -> np.ndarray:
    """Read a whitespace table written by getdp (np.loadtxt: the fastest reader measured here)."""
    return np.loadtxt(path, ndmin=2)


def element_volumes(mesh: EMMesh, rows: np.ndarray, axisymmetric: bool) -> np.ndarray:
    """Volumes of the triangles ``rows`` (2 pi r_c A in axisymmetry, A in planar)."""
    p = mesh.points[mesh.triangles[rows]]
    d1, d2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    a = 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    return 2 * np.pi * p[:, :, 0].mean(axis=1) * a if axisymmetric else a
