"""Carry a GetDP solution vector to a new mesh through the dof numbering of both ``.pre`` files.

A deck whose state travels by ``-restart -res`` only (a deck on GetDP's template: :mod:`.template`)
needs, after its mesh was remeshed, a ``.res`` numbered as the new mesh's dofs. GetDP writes each
run's dof numbering to ``<name>.pre`` (``$DofData``: one line per dof, ``FunctionSpace Entity
Harmonic Type ...``; types 1 (unknown) and 5 (unknown with an Init value) carry their equation
number in the fifth field); a ``-pre`` run on the new mesh gives the new numbering. Every unknown
of the new mesh then takes the value of the same dof of the old one:

* a function space of global quantities (the regions' currents and voltages, the circuit's: the
  same entities in both ``.pre`` files, and fewer than :data:`MAX_GLOBAL` unknowns) keeps each
  value by key; where the node map keeps every one of its entities (node k stays node k) the two
  readings agree anyway;
* any other space is nodal: its entity is a mesh node (1-based), mapped through ``old_node`` (the
  old node of each new node, -1 for a new node); a new node takes the value of the nearest old node
  of that space — only nodes in the air are new, and air values do not enter an implicit step's
  time derivatives (sigma = 0 there). A nodal space with fewer than :data:`MAX_GLOBAL` unknowns and
  the same entities in both meshes would be read as global: meshes that are remeshed have more nodes.

An unknown of a global space missing from the old numbering raises :class:`RemapError`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["RemapError", "read_pre_dofs", "remap_solution", "MAX_GLOBAL"]

#: a function space with the same entities in both numberings and fewer unknowns is one of global quantities
MAX_GLOBAL = 64


class RemapError(ValueError):
    """The solution cannot be carried to the new dof numbering (one line)."""


def read_pre_dofs(path: str | Path) -> dict[tuple[int, int, int], int]:
    """The unknowns of a GetDP 3.2.0 ``.pre`` (one DofData): (function space, entity, harmonic) -> the
    0-based equation index (types 1 and 5; fixed and linked dofs are not unknowns)."""
    text = Path(path).read_text()
    blocks = text.split("$DofData")[1:]
    if len(blocks) != 1:
        raise RemapError(f"{path}: {len(blocks)} DofData blocks; the remap handles one system")
    lines = blocks[0].split("$EndDofData")[0].strip().splitlines()[1:]
    # the header ends with the line "<number of dofs> <number of unknowns>"; one line per dof follows
    start = next((i + 1 for i, ln in enumerate(lines) if len(ln.split()) == 2
                  and ln.split()[0].isdigit() and int(ln.split()[0]) == len(lines) - i - 1), None)
    if start is None:
        raise RemapError(f"{path}: no dof list in its DofData")
    out: dict[tuple[int, int, int], int] = {}
    for ln in lines[start:]:
        f = ln.split()
        if len(f) >= 6 and f[3] in ("1", "5"):
            out[(int(f[0]), int(f[1]), int(f[2]))] = int(f[4]) - 1
    if not out:
        raise RemapError(f"{path}: no unknown in its DofData")
    return out


def remap_solution(old: dict[tuple[int, int, int], int], new: dict[tuple[int, int, int], int],
                   x_old: np.ndarray, old_node: np.ndarray, old_points: np.ndarray,
                   new_points: np.ndarray) -> np.ndarray:
    """The solution ``x_old`` (numbered by ``old``) on the unknowns ``new`` (module docstring).

    Parameters
    ----------
    old, new : dict
        :func:`read_pre_dofs` of the old and the new mesh.
    x_old : ndarray
        The old solution vector.
    old_node : ndarray of int
        For each new node (0-based), its old node (0-based), or -1 for a new node.
    old_points, new_points : ndarray (N, 2)
        Node coordinates (m) of the old and new mesh, for the nearest-node fill of new nodes.

    Returns
    -------
    ndarray
        The new solution vector (length: the number of new unknowns).
    """
    from scipy.spatial import cKDTree

    x_old = np.asarray(x_old, float)
    x = np.full(len(new), np.nan)
    spaces = {k[0] for k in new}
    for fs in sorted(spaces):
        ent_old = {k[1] for k in old if k[0] == fs}
        keys = [k for k in new if k[0] == fs]
        ents = np.array(sorted({k[1] for k in keys}), dtype=np.int64)
        same = set(ents.tolist()) == ent_old
        kept = bool(len(ents)) and ents.max() <= len(old_node) and bool(np.all(old_node[ents - 1] == ents - 1))
        if same and (len(keys) < MAX_GLOBAL or kept):
            for k in keys:
                x[new[k]] = x_old[old[k]]
            continue
        nodes_old = np.array(sorted(ent_old), dtype=np.int64)
        if not len(nodes_old) or nodes_old.max() > len(old_points):
            raise RemapError(f"function space {fs}: its entities differ between the meshes and are not all nodes")
        tree = cKDTree(old_points[nodes_old - 1, :2])
        for k in keys:
            o = int(old_node[k[1] - 1]) + 1 if k[1] <= len(old_node) else 0
            if o > 0 and (fs, o, k[2]) in old:
                x[new[k]] = x_old[old[(fs, o, k[2])]]
            else:  # a new (air) node, or a kept node new to this space: the nearest old node's value
                near = int(nodes_old[tree.query(new_points[k[1] - 1, :2])[1]])
                x[new[k]] = x_old[old[(fs, near, k[2])]] if (fs, near, k[2]) in old else 0.0
    if np.isnan(x).any():
        raise RemapError(f"{int(np.isnan(x).sum())} unknowns of the new mesh have no value")
    return x
