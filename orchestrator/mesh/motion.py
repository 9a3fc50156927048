"""Move the EM mesh with the conductors: air nodes follow by harmonic (Laplacian) smoothing.

Conductor nodes take the mechanical displacement, fixed parts (coil, outer boundary, shell, axis
in r) stay or slide as told, and the displacement of every other node solves the P1 Laplace
equation with those values as Dirichlet data. The stiffness is assembled and factorised once, on
the reference mesh; each update is one back-substitution. Element quality is watched, and an
inverted or degenerate element raises :class:`MeshQualityError` before the mesh can reach GetDP.
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from .triangles import triangle_areas

log = logging.getLogger(__name__)


class MeshQualityError(RuntimeError):
    """The moved mesh has an inverted element or its quality fell below the threshold."""


def triangle_quality(x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Shape quality 4√3 A / (l1² + l2² + l3²): 1 for equilateral, 0 degenerate, < 0 inverted."""
    a, b, c = x[cells[:, 0]], x[cells[:, 1]], x[cells[:, 2]]
    l2 = ((b - a) ** 2).sum(1) + ((c - b) ** 2).sum(1) + ((a - c) ** 2).sum(1)
    return 4.0 * np.sqrt(3.0) * triangle_areas(x, cells) / l2


def laplacian(x: np.ndarray, cells: np.ndarray) -> sp.csr_matrix:
    """P1 stiffness matrix of −Δ (cotangent weights) on the mesh (x, cells)."""
    n = x.shape[0]
    rows, cols, vals = [], [], []
    area = np.abs(triangle_areas(x, cells))
    p = x[cells]  # (M, 3, 2)
    # gradients of barycentric functions: ∇λ_i = rot(p_k − p_j) / (2A)
    grads = np.empty((len(cells), 3, 2))
    for i, (j, k) in enumerate(((1, 2), (2, 0), (0, 1))):
        e = p[:, k] - p[:, j]
        grads[:, i, 0] = -e[:, 1]
        grads[:, i, 1] = e[:, 0]
    sign = np.sign(triangle_areas(x, cells))[:, None, None]
    grads = grads * sign / (2.0 * area[:, None, None])
    ke = area[:, None, None] * np.einsum("mid,mjd->mij", grads, grads)
    for i in range(3):
        for j in range(3):
            rows.append(cells[:, i])
            cols.append(cells[:, j])
            vals.append(ke[:, i, j])
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))


class MeshMover:
    """Harmonic extension of prescribed displacements to the remaining nodes, per component.

    Parameters
    ----------
    x_ref : ndarray (N, 2)
        Reference node coordinates (m).
    cells : ndarray (M, 3)
        Triangles of the whole EM mesh.
    prescribed : ndarray of int, or (ndarray, ndarray)
        Nodes whose displacement is given at each update (conductors that move, fixed parts);
        a pair gives separate sets for the x (r) and y (z) components, e.g. axis nodes that may
        slide along z but not leave r = 0.
    min_quality : float
        Smallest acceptable :func:`triangle_quality` (0 < q ≤ 1).
    """

    def __init__(self, x_ref: np.ndarray, cells: np.ndarray, prescribed, min_quality: float = 0.05) -> None:
        self.x_ref = np.asarray(x_ref, dtype=float)[:, :2].copy()
        self.cells = np.asarray(cells)
        self.min_quality = min_quality
        n = self.x_ref.shape[0]
        if isinstance(prescribed, tuple):
            sets = [np.unique(np.asarray(p, dtype=np.int64)) for p in prescribed]
        else:
            sets = [np.unique(np.asarray(prescribed, dtype=np.int64))] * 2
        K = laplacian(self.x_ref, self.cells).tocsc()
        self._parts = []
        for fixed in sets:
            mask = np.ones(n, dtype=bool)
            mask[fixed] = False
            free = np.flatnonzero(mask)
            lu = splu(K[free][:, free].tocsc()) if len(free) else None
            self._parts.append((fixed, free, K[free][:, fixed], lu))
        self.q_ref = triangle_quality(self.x_ref, self.cells)
        self.last_min_quality = float(self.q_ref.min())

    def displace(self, u_given: np.ndarray) -> np.ndarray:
        """Displacement (N, 2) of every node; ``u_given`` (N, 2) holds the values on the prescribed
        nodes of each component (other entries are ignored)."""
        u = np.zeros_like(self.x_ref)
        for d, (fixed, free, k_fp, lu) in enumerate(self._parts):
            u[fixed, d] = u_given[fixed, d]
            if lu is not None:
                u[free, d] = lu.solve(np.ascontiguousarray(-(k_fp @ u_given[fixed, d])))
        return u

    def moved(self, u_given: np.ndarray) -> np.ndarray:
        """Moved coordinates (m), after checking element quality.

        Raises
        ------
        MeshQualityError
            An element is inverted, or the worst quality is below ``min_quality``.
        """
        x = self.x_ref + self.displace(u_given)
        q = triangle_quality(x, self.cells)
        self.last_min_quality = float(q.min())  # also when the check below raises
        self.last_min_quality = check_quality(x, self.cells, q, self.min_quality, "element", "remesh needed")
        return x  # the worst quality of each step goes to the history (em_mesh_min_quality), not the log


def check_quality(x: np.ndarray, cells: np.ndarray, q: np.ndarray, min_quality: float, kind: str,
                  action: str) -> float:
    """The worst of the element qualities ``q`` (of ``cells`` at positions ``x``, m).

    Raises
    ------
    MeshQualityError
        The worst element is inverted (q <= 0) or below ``min_quality``: named as ``kind`` with its
        index, quality and centre, followed by ``action``.
    """
    worst = int(np.argmin(q))
    if q[worst] <= 0.0:
        raise MeshQualityError(f"{kind} {worst} inverted (quality {q[worst]:.3g}) at "
                               f"{x[cells[worst]].mean(0)} m: {action}")
    if q[worst] < min_quality:
        raise MeshQualityError(f"{kind} {worst} quality {q[worst]:.3g} < {min_quality:.3g} at "
                               f"{x[cells[worst]].mean(0)} m: {action}")
    return float(q[worst])
