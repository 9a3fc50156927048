"""The mechanical meshes of 3D conductors, cut from the 3D EM mesh so that both share their nodes.

The 3D counterpart of :mod:`.shared`: a conductor region (physical id 200 + k) of a
:class:`~pulseform.solvers.getdp.mesh3d.Mesh3D` becomes a DOLFINx P1-tetrahedron mesh with exactly
its nodes and tetrahedra, and each mechanical node is matched to its EM node (by position: DOLFINx
renumbers nodes when it builds a mesh).
"""

from __future__ import annotations

import numpy as np

from pulseform.solvers.getdp.mesh3d import Mesh3D

from .shared import ConductorMesh, match_nodes, to_dolfinx


class ConductorMesh3D(ConductorMesh):
    """A conductor region of the 3D EM mesh as its own mesh: :class:`~.shared.ConductorMesh` with
    ``points`` (n, 3) m and ``cells`` (m, 4) tetrahedra (local node rows, positively oriented)."""

    def skin_faces(self) -> np.ndarray:
        """The boundary triangles (f, 3) as local node rows (faces of one cell only)."""
        faces = self.cells[:, [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]]].reshape(-1, 3)
        _, inv, cnt = np.unique(np.sort(faces, axis=1), axis=0, return_inverse=True, return_counts=True)
        return faces[cnt[inv.ravel()] == 1]


def conductor_submesh3d(em: Mesh3D, tag: int) -> ConductorMesh3D:
    """Tetrahedra of physical region ``tag`` with their nodes renumbered from 0 in EM order, positively
    oriented (cell j is the EM tetrahedron ``rows[j]``, two of its nodes swapped where it was not)."""
    rows = np.flatnonzero(em.tet_tags == tag)
    if rows.size == 0:
        raise ValueError(f"region {tag} is empty in the 3D EM mesh")
    nodes, inverse = np.unique(em.tets[rows], return_inverse=True)
    cells = inverse.reshape(-1, 4).copy()
    p = em.points[nodes]
    x = p[cells]
    det = np.einsum("ij,ij->i", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0])
    if np.any(det == 0):
        raise ValueError(f"region {tag}: degenerate tetrahedra")
    neg = det < 0
    cells[neg] = cells[neg][:, [0, 2, 1, 3]]
    return ConductorMesh3D(rows, nodes, p.copy(), cells)


#: the 2D functions take 3D submeshes too (one home): P1 tetrahedra, node matching in 3 coordinates
to_dolfinx3d = to_dolfinx
match_nodes3d = match_nodes
