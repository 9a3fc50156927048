"""What the persistent getdp and Python exchange besides the FIFO lines: the unknowns of a system in getdp's
``.pre`` (:func:`read_pre_dofs`, :func:`nodal_dof_map`), the solution vectors of a binary ``.res``
(:func:`read_binary_res`), and node increments that land exactly (:func:`exact_increment`)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["exact_increment", "read_pre_dofs", "read_binary_res", "nodal_dof_map"]

#: dof types of getdp's ``.pre`` that are unknowns of the system (a number in the solution vector):
#: unknown, unknown with an Init value
_UNKNOWN_TYPES = (1, 5)


def exact_increment(x: np.ndarray, target: np.ndarray) -> np.ndarray:
    """An increment u with ``x + u == target`` in IEEE double arithmetic, elementwise: getdp's
    ``DeformMesh`` adds u to its node coordinates, so that its nodes land exactly on ``target`` (not one
    unit in the last place off, as x + (target - x) can be: a process started from a mesh file at
    ``target`` then has the same coordinates, bit for bit). u = target - x, then moved by single units in
    the last place where the sum misses (a few at most); where none hits, the nearest one stays."""
    u = target - x
    for _ in range(8):
        s = x + u
        miss = s != target
        if not miss.any():
            break
        u[miss] = np.nextafter(u[miss], np.where(s[miss] < target[miss], np.inf, -np.inf))
    return u


def read_pre_dofs(path: Path, system: int) -> np.ndarray:
    """Rows (NumType, Entity, Harmonic, Type, NumDof) of DofData #``system`` in a getdp ``.pre`` file."""
    text = Path(path).read_text()
    head = f"$DofData /* #{system} */"
    i = text.find(head)
    if i < 0:
        raise RuntimeError(f"{path}: no {head}")
    lines = text[i:text.find("$EndDofData", i)].splitlines()
    n_any = int(lines[5].split()[0])
    return np.array([ln.split()[:5] for ln in lines[6:6 + n_any]], dtype=np.int64)


def read_binary_res(path: Path, n_dofs: int) -> list[np.ndarray]:
    """The solution vectors (``n_dofs`` doubles each) of a binary GetDP ``.res`` file, in order."""
    data = Path(path).read_bytes()
    out, pos = [], 0
    while True:
        i = data.find(b"$Solution", pos)
        if i < 0:
            return out
        start = data.index(b"\n", data.index(b"\n", i) + 1) + 1  # after the "$Solution" and header lines
        out.append(np.frombuffer(data, "<f8", n_dofs, start).copy())
        pos = data.index(b"$EndSolution", start + 8 * n_dofs)


def nodal_dof_map(pre: Path, system: int, n_nodes: int) -> tuple[np.ndarray, int]:
    """(index of each node's unknown in the solution vector of system ``system``, -1 where the node has
    none (a Dirichlet node), number of unknowns) from getdp's ``.pre`` (rows ``NumType Entity Harmonic
    Type NumDof ...``; Type 1 an unknown, 5 an unknown with an Init value, 2 a fixed value): the nodal
    basis function is the most frequent one of the system."""
    rows = read_pre_dofs(pre, system)
    unknown = np.isin(rows[:, 3], _UNKNOWN_TYPES)
    kinds, counts = np.unique(rows[:, 0], return_counts=True)
    nodal = rows[(rows[:, 0] == kinds[np.argmax(counts)]) & unknown]
    index = np.full(n_nodes, -1, np.int64)
    index[nodal[:, 1] - 1] = nodal[:, 4] - 1
    return index, int(rows[unknown, 4].max())
