"""Transfer of EM loads onto the mechanical mesh: consistent nodal forces and their ledger.

All meshes here are P1 triangles: ``x`` (N, 2) node coordinates in m, ``cells`` (M, 3) node indices.
Planar integrals are per ``thickness`` (m) of depth; axisymmetric ones (x = r, y = z) are over the
full ring, with the weight 2πr.

For a cell force density f_e (N/m³, constant per cell, as GetDP prints it per element), the
consistent nodal force is F_i = Σ_e f_e ∫_e N_i w dA with w = thickness or 2πr. For a linear
triangle of area A with nodal radii r_i, r_j, r_k:

* planar:        ∫ N_i dA = A / 3
* axisymmetric:  ∫ N_i 2πr dA = 2π A (2 r_i + r_j + r_k) / 12

Summed over i, these give the cell volume exactly (partition of unity; Pappus for the ring), so
Σ_i F_i = Σ_e f_e V_e to round-off: the transfer is conservative by construction and the ledger
checks it every EM step.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..mesh.triangles import boundary_facets, triangle_areas  # noqa: F401  (also used by the transfer's callers)


def nodal_volume_weights(x: np.ndarray, cells: np.ndarray, *, axisymmetric: bool,
                         thickness: float = 1.0) -> np.ndarray:
    """∫_e N_i w dA for each cell and each of its 3 nodes, shape (M, 3), in m³."""
    area = np.abs(triangle_areas(x, cells))
    if not axisymmetric:
        return np.repeat((thickness * area / 3.0)[:, None], 3, axis=1)
    r = x[cells, 0]  # (M, 3)
    return 2.0 * np.pi * area[:, None] * (r + r.sum(axis=1, keepdims=True)) / 12.0


def cell_volumes(x: np.ndarray, cells: np.ndarray, *, axisymmetric: bool, thickness: float = 1.0) -> np.ndarray:
    """Cell volumes (m³): thickness·A planar, 2π r_c A axisymmetric."""
    return nodal_volume_weights(x, cells, axisymmetric=axisymmetric, thickness=thickness).sum(axis=1)


def cell_to_nodal_forces(x: np.ndarray, cells: np.ndarray, f_cell: np.ndarray, *, axisymmetric: bool,
                         thickness: float = 1.0) -> np.ndarray:
    """Consistent nodal forces (N), shape (N, 2), of a per-cell force density ``f_cell`` (M, 2) in N/m³."""
    w = nodal_volume_weights(x, cells, axisymmetric=axisymmetric, thickness=thickness)
    out = np.zeros((x.shape[0], 2))
    idx = cells.ravel()
    for d in range(2):
        out[:, d] = np.bincount(idx, weights=(w * f_cell[:, d:d + 1]).ravel(), minlength=x.shape[0])
    return out


def cell_force_integral(x: np.ndarray, cells: np.ndarray, f_cell: np.ndarray, *, axisymmetric: bool,
                        thickness: float = 1.0) -> np.ndarray:
    """∫ f dV = Σ_e f_e V_e (N), shape (2,)."""
    v = cell_volumes(x, cells, axisymmetric=axisymmetric, thickness=thickness)
    return (f_cell * v[:, None]).sum(axis=0)


def ledger_error(nodal: np.ndarray, integral: np.ndarray) -> float:
    """|Σ nodal F − ∫ f dV| / |∫ f dV| (0 when both vanish)."""
    total = nodal.sum(axis=0)
    ref = float(np.linalg.norm(integral))
    diff = float(np.linalg.norm(total - integral))
    return diff / ref if ref > 0.0 else diff


def pressure_to_nodal_forces(x: np.ndarray, facets: np.ndarray, pressure: float, *, axisymmetric: bool,
                             thickness: float = 1.0) -> np.ndarray:
    """Consistent nodal forces (N) of a pressure (Pa) pushing into the body on oriented ``facets``.

    ``facets`` have the body on their left (see :func:`boundary_facets`), so the outward normal of
    edge (a → b) is (dy, −dx)/L and the pressure force is −p n_out L per unit depth. Axisymmetric:
    ∫ N_a 2πr dL = 2π L (2 r_a + r_b) / 6.
    """
    a, b = x[facets[:, 0]], x[facets[:, 1]]
    d = b - a
    n_len = np.stack([d[:, 1], -d[:, 0]], axis=1)  # outward normal times L
    if axisymmetric:
        wa = 2.0 * np.pi * (2.0 * a[:, 0] + b[:, 0]) / 6.0
        wb = 2.0 * np.pi * (a[:, 0] + 2.0 * b[:, 0]) / 6.0
    else:
        wa = wb = np.full(len(facets), thickness / 2.0)
    out = np.zeros((x.shape[0], 2))
    for d_ in range(2):
        out[:, d_] += np.bincount(facets[:, 0], weights=-pressure * n_len[:, d_] * wa, minlength=x.shape[0])
        out[:, d_] += np.bincount(facets[:, 1], weights=-pressure * n_len[:, d_] * wb, minlength=x.shape[0])
    return out


def locate_cells(x: np.ndarray, cells: np.ndarray, points: np.ndarray, k: int = 12) -> np.ndarray:
    """Index of the cell of (x, cells) containing each point, −1 where none does.

    Candidates are the ``k`` cells with the nearest centroids; the first whose barycentric
    coordinates are all ≥ −1e-10 wins.
    """
    centroids = x[cells].mean(axis=1)
    tree = cKDTree(centroids)
    k = min(k, len(cells))
    _, cand = tree.query(points, k=k)
    cand = np.atleast_2d(cand.reshape(len(points), -1))
    out = np.full(len(points), -1, dtype=np.int64)
    for j in range(cand.shape[1]):
        todo = out < 0
        if not todo.any():
            break
        c = cand[todo, j]
        lam = barycentric(x, cells[c], points[todo])
        ok = (lam >= -1e-10).all(axis=1)
        idx = np.flatnonzero(todo)[ok]
        out[idx] = c[ok]
    return out


def barycentric(x: np.ndarray, tri: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Barycentric coordinates (P, 3) of points ``p`` (P, 2) in triangles ``tri`` (P, 3)."""
    a, b, c = x[tri[:, 0]], x[tri[:, 1]], x[tri[:, 2]]
    v0, v1, v2 = b - a, c - a, p - a
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    l1 = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
    l2 = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
    return np.stack([1.0 - l1 - l2, l1, l2], axis=1)


def project_cell_field(src_x: np.ndarray, src_cells: np.ndarray, f_src: np.ndarray,
                       dst_x: np.ndarray, dst_cells: np.ndarray) -> np.ndarray:
    """Per-cell field on a non-matching mesh, by the 3-point (degree-2) rule on each target cell.

    Each target cell takes the mean of the source values at its three quadrature points
    (barycentric (2/3, 1/6, 1/6) and permutations); points outside the source mesh count as zero.
    The caller's ledger (:func:`ledger_error` against the source integral) reports what this loses.
    """
    lam = np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])
    tri = dst_x[dst_cells]  # (M, 3, 2)
    out = np.zeros((len(dst_cells), f_src.shape[1]))
    for q in lam:
        pts = np.einsum("k,mkd->md", q, tri)
        owner = locate_cells(src_x, src_cells, pts)
        found = owner >= 0
        out[found] += f_src[owner[found]] / 3.0
    return out
