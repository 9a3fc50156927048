"""Renumbering a GetDP solution to a remeshed mesh's dofs (solvers/getdp/res_remap.py), on small
hand-written .pre files in GetDP 3.2.0's format (as em.pre of a template-deck run: function space 1
nodal, 7 and 13 global; type 1 unknowns, 2 fixed, 3 fixed with an associate, 5 unknown with an Init).
The coupled check of the whole path is tests/workflow/test_user_remesh.py (template vs library deck)."""

from __future__ import annotations

import numpy as np
import pytest

from pulseform.solvers.getdp.res_remap import RemapError, read_pre_dofs, remap_solution


def _pre(path, dofs):
    head = "$Resolution /* 'EM_Transient' */\n2 1\n$EndResolution\n$DofData /* #0 */\n2 0\n3 0 1 2\n1 0\n1 0\n"
    n_unknown = sum(1 for d in dofs if d[3] in (1, 5))
    body = "\n".join(" ".join(str(v) for v in d) for d in dofs)
    path.write_text(head + f"{len(dofs)} {n_unknown}\n{body}\n$EndDofData\n")
    return path


def test_unknowns_are_carried_by_key_and_through_the_kept_nodes(tmp_path):
    """101 nodes on a line, node 1 fixed (the axis); the remesh removes air node 50 and adds a new node
    (number 101) at x = 49.9: the same node numbers as before, but not the same nodes — the case where
    only the node map tells them apart. The globals come in another order."""
    n = 101
    old_dofs = [(1, 1, 0, 2, 0, 0)] + [(1, k, 0, 1, k - 1, 1) for k in range(2, n + 1)]
    old_dofs += [(5, 1200, 0, 3, n, 0, 0), (7, 1200, 0, 1, n, -1), (13, 5001, 0, 5, n + 1, 6000, 0, -1)]
    old = read_pre_dofs(_pre(tmp_path / "old.pre", old_dofs))
    assert old[(1, 2, 0)] == 0 and old[(7, 1200, 0)] == n - 1 and old[(13, 5001, 0)] == n and len(old) == n + 1
    new_dofs = [(1, 1, 0, 2, 0, 0), (13, 5001, 0, 5, 1, 6000, 0, -1), (7, 1200, 0, 1, 2, -1)]
    new_dofs += [(1, k, 0, 1, 2 + k - 1, 1) for k in range(n, 1, -1)]  # the nodes numbered backwards
    new = read_pre_dofs(_pre(tmp_path / "new.pre", new_dofs))
    old_points = np.column_stack([np.arange(n, dtype=float), np.zeros(n)])  # node k at x = k - 1
    keep = np.arange(n) != 49  # old node 50 (x = 49) removed
    new_points = np.vstack([old_points[keep], [[49.9, 0.0]]])
    old_node = np.concatenate([np.flatnonzero(keep), [-1]])
    x_old = np.concatenate([100.0 + np.arange(2, n + 1), [-7.0, 5500.0]])  # node k holds 100 + k
    x = remap_solution(old, new, x_old, old_node, old_points, new_points)
    assert x[new[(13, 5001, 0)]] == 5500.0 and x[new[(7, 1200, 0)]] == -7.0
    want = {k: 100.0 + old_node[k - 1] + 1 for k in range(2, n)}  # kept nodes: the old node's value
    want[n] = 100.0 + 51  # the new node at x = 49.9: the nearest old node is node 51 (x = 50)
    assert {k: x[new[(1, k, 0)]] for k in range(2, n + 1)} == want


def test_a_global_unknown_missing_from_the_old_numbering_is_refused(tmp_path):
    old = read_pre_dofs(_pre(tmp_path / "old.pre", [(1, 1, 0, 1, 1, 1), (7, 1200, 0, 1, 2, -1)]))
    new = read_pre_dofs(_pre(tmp_path / "new.pre", [(1, 1, 0, 1, 1, 1), (7, 1201, 0, 1, 2, -1)]))
    with pytest.raises(RemapError, match="not all nodes"):
        remap_solution(old, new, np.array([1.0, 2.0]), np.array([0]), np.zeros((1, 2)), np.zeros((1, 2)))
