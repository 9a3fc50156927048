"""Frictionless sliding on symmetry planes of any orientation (3D bodies).

A node on a symmetry plane keeps its normal velocity and acceleration at zero and moves freely in
the plane; a node on two planes (the axis of a sector, an edge of a quarter) moves along their
common line. Planes along x, y or z can use ``BodySpec.fixed`` (one velocity component); an oblique
plane (the second face of a sector at angle θ) couples the components, so its nodes' velocity and
acceleration are projected: u ← u − Σ_k (u·p_k) p_k with p_k an orthonormal basis of the normals of
the planes the node lies on. The constraint forces are normal to the planes and do no work.
"""
from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

__all__ = ["SlidingPlanes"]


class SlidingPlanes:
    """The sliding constraints of one body.

    Parameters
    ----------
    X : ndarray (N, 3)
        Reference node coordinates (m).
    planes : sequence of (marker, normal)
        ``marker(x) -> bool array`` over coordinates (3, N) (reference configuration), ``normal`` the
        plane's normal (3 components, any length).
    """

    def __init__(self, X: np.ndarray, planes: Sequence[tuple[Callable, Sequence[float]]]) -> None:
        normals: dict[int, list[np.ndarray]] = {}
        for marker, nrm in planes:
            n = np.asarray(nrm, float)
            if n.shape != (3,) or not np.linalg.norm(n) > 0:
                raise ValueError(f"a sliding plane needs a non-zero 3-component normal, got {nrm!r}")
            n = n / np.linalg.norm(n)
            for i in np.flatnonzero(np.asarray(marker(X.T.copy()), dtype=bool)).tolist():
                normals.setdefault(i, []).append(n)
        self.nodes = np.array(sorted(normals), dtype=np.int64)
        self.basis = np.zeros((len(self.nodes), 3, 3))   # rows: orthonormal normals, zero rows unused
        for j, i in enumerate(self.nodes.tolist()):
            k = 0
            for u in normals[i]:
                w = u - self.basis[j, :k].T @ (self.basis[j, :k] @ u)
                if np.linalg.norm(w) > 1e-8 and k < 3:
                    self.basis[j, k] = w / np.linalg.norm(w)
                    k += 1

    def project(self, arr: np.ndarray) -> None:
        """Remove, in place, the normal components of the nodal vectors ``arr`` (N, 3) on the planes."""
        if self.nodes.size == 0:
            return
        a = arr[self.nodes]
        c = np.einsum("mki,mi->mk", self.basis, a)
        arr[self.nodes] = a - np.einsum("mk,mki->mi", c, self.basis)
