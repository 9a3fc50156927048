"""Move a 3D EM mesh with the conductors: the air follows by harmonic (Laplace) extension.

The 3D counterpart of :mod:`.motion`. Conductor nodes take the mechanical displacement, fixed
parts (coil, shell, outer boundary) stay, nodes on a symmetry plane slide in it (their normal
displacement is zero; a node on two planes, e.g. the axis of a sector, slides along their common
line), and the displacement of every other node solves the P1 vector Laplace equation with those
values. Sliding on an oblique plane couples the components, so the system is written in a local
basis per constrained node (normal(s) first), factorised once on the reference mesh; each update is
one back-substitution. Element quality (mean ratio) is watched, and an inverted or degenerate
tetrahedron raises :class:`~.motion.MeshQualityError` before the mesh can reach GetDP.
"""

from __future__ import annotations

import logging
from typing import Sequence

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from .motion import MeshQualityError, check_quality

log = logging.getLogger(__name__)

__all__ = ["MeshMover3D", "tet_quality", "tet_laplacian", "nodes_on_plane"]


def _signed_volumes(x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    p = x[cells]
    return np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) / 6.0


def tet_quality(x: np.ndarray, cells: np.ndarray, sign: np.ndarray | None = None) -> np.ndarray:
    """Mean-ratio quality 12 (3|V|)^(2/3) / Σ l² of tetrahedra: 1 regular, 0 degenerate; negative
    where the orientation differs from ``sign`` (the reference signs of the volumes: inverted)."""
    v = _signed_volumes(x, cells)
    p = x[cells]
    l2 = sum(((p[:, i] - p[:, j]) ** 2).sum(1) for i, j in ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)))
    q = 12.0 * np.cbrt(3.0 * np.abs(v)) ** 2 / l2
    s = np.sign(v) if sign is None else np.sign(v) * sign
    return q * s


def tet_laplacian(x: np.ndarray, cells: np.ndarray) -> sp.csr_matrix:
    """P1 stiffness matrix of −Δ on the tetrahedral mesh (x, cells)."""
    n = x.shape[0]
    p = x[cells]
    jac = np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]], axis=1)  # (M, 3, 3) rows
    inv = np.linalg.inv(jac)  # columns: gradients of the barycentric functions 1..3
    g = np.concatenate([-inv.sum(axis=2, keepdims=True), inv], axis=2)  # (M, 3, 4)
    vol = np.abs(np.linalg.det(jac)) / 6.0
    ke = vol[:, None, None] * np.einsum("mdi,mdj->mij", g, g)
    rows = np.repeat(cells, 4, axis=1).ravel()
    cols = np.tile(cells, (1, 4)).ravel()
    return sp.csr_matrix((ke.ravel(), (rows, cols)), shape=(n, n))


def nodes_on_plane(x: np.ndarray, point: Sequence[float], normal: Sequence[float], tol: float) -> np.ndarray:
    """Indices of the nodes within ``tol`` (m) of the plane through ``point`` with ``normal``."""
    n = np.asarray(normal, float)
    n = n / np.linalg.norm(n)
    return np.flatnonzero(np.abs((x - np.asarray(point, float)) @ n) <= tol)


def _local_bases(n_nodes: int, planes: Sequence[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Per node an orthonormal basis (rows) whose first ``k`` vectors span the normals of the planes
    the node lies on (Gram-Schmidt), and ``k`` (0 for a node on no plane)."""
    normals: dict[int, list[np.ndarray]] = {}
    for nodes, nrm in planes:
        u = np.asarray(nrm, float) / np.linalg.norm(nrm)
        for i in np.asarray(nodes).tolist():
            normals.setdefault(i, []).append(u)
    q = np.tile(np.eye(3), (n_nodes, 1, 1))
    k = np.zeros(n_nodes, dtype=np.int64)
    for i, ns in normals.items():
        basis: list[np.ndarray] = []
        for u in ns + [np.eye(3)[j] for j in range(3)]:
            w = u - sum((u @ b) * b for b in basis)
            if np.linalg.norm(w) > 1e-8:
                basis.append(w / np.linalg.norm(w))
                if len(basis) == 3:
                    break
        q[i] = np.array(basis)
        k[i] = int(np.linalg.matrix_rank(np.array(ns), tol=1e-8))  # the same plane twice counts once
    return q, k


class MeshMover3D:
    """Harmonic extension of prescribed displacements into the air of a 3D mesh (module docstring).

    Parameters
    ----------
    x_ref : ndarray (N, 3)
        Reference node coordinates (m).
    cells : ndarray (M, 4)
        Tetrahedra of the whole EM mesh.
    prescribed : ndarray of int
        Nodes whose whole displacement is given at each update (conductors, coil, shell, outer boundary).
    planes : sequence of (nodes, normal)
        Symmetry planes: their nodes (not prescribed ones) slide in them.
    min_quality : float
        Smallest acceptable :func:`tet_quality` (0 < q <= 1); below it :meth:`moved` raises.
    """

    def __init__(self, x_ref: np.ndarray, cells: np.ndarray, prescribed: np.ndarray,
                 planes: Sequence[tuple[np.ndarray, np.ndarray]] = (), min_quality: float = 0.02) -> None:
        self.x_ref = np.asarray(x_ref, float)[:, :3].copy()
        self.cells = np.asarray(cells)
        self.min_quality = min_quality
        n = len(self.x_ref)
        self.prescribed = np.unique(np.asarray(prescribed, dtype=np.int64))
        q, k = _local_bases(n, planes)
        k[self.prescribed] = 3
        self.q, self.k = q, k
        # local dofs: node i, component c (in its basis); fixed where c < k_i
        K = tet_laplacian(self.x_ref, self.cells)
        r = (3 * np.arange(n)[:, None, None] + np.arange(3)[None, :, None]) + 0 * np.arange(3)[None, None, :]
        c = (3 * np.arange(n)[:, None, None] + np.arange(3)[None, None, :]) + 0 * np.arange(3)[None, :, None]
        T = sp.csr_matrix((q.ravel(), (r.ravel(), c.ravel())), shape=(3 * n, 3 * n))  # block-diagonal: rows of q
        K3 = sp.kron(K, sp.identity(3), format="csr")
        Kt = (T @ K3 @ T.T).tocsc()
        fixed_mask = (np.arange(3)[None, :] < k[:, None]).ravel()
        self._T = T
        self._fixed = np.flatnonzero(fixed_mask)
        self._free = np.flatnonzero(~fixed_mask)
        self._k_fp = Kt[self._free][:, self._fixed]
        self._lu = splu(Kt[self._free][:, self._free].tocsc()) if len(self._free) else None
        self._sign = np.sign(_signed_volumes(self.x_ref, self.cells))
        self.q_ref = tet_quality(self.x_ref, self.cells, self._sign)
        self.last_min_quality = float(self.q_ref.min())
        log.info("3D mesh motion: %d nodes, %d prescribed, %d on symmetry planes, %d free unknowns",
                 n, len(self.prescribed), int(np.sum((k > 0) & (k < 3))), len(self._free))

    def displace(self, u_given: np.ndarray) -> np.ndarray:
        """Displacement (N, 3) m of every node; ``u_given`` holds the values of the prescribed nodes."""
        n = len(self.x_ref)
        ug = np.zeros((n, 3))
        ug[self.prescribed] = np.asarray(u_given, float)[self.prescribed]
        ut = (self._T @ ug.ravel())   # local components; zero normal displacement on the planes
        if self._lu is not None:
            ut[self._free] = self._lu.solve(np.ascontiguousarray(-(self._k_fp @ ut[self._fixed])))
        return (self._T.T @ ut).reshape(n, 3)

    def moved(self, u_given: np.ndarray) -> np.ndarray:
        """Moved coordinates (m), after checking element quality.

        Raises
        ------
        MeshQualityError
            A tetrahedron is inverted, or the worst quality is below ``min_quality``.
        """
        x = self.x_ref + self.displace(u_given)
        q = tet_quality(x, self.cells, self._sign)
        self.last_min_quality = float(q.min())  # also when the check below raises
        self.last_min_quality = check_quality(x, self.cells, q, self.min_quality, "tetrahedron",
                                              "the 3D air mesh needs a remesh (not done in 3D yet)")
        return x
