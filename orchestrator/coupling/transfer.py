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

Six-node bodies (``element = "tri6"``, :mod:`pulseform.solvers.dolfinx.tri6`: the EM mesh's vertices first, then
one node per edge; :func:`body_forces`): the force f_e V_e of each EM triangle goes to the six nodes of its
mechanical cell in the proportions of their HRZ lumped masses (:func:`~pulseform.solvers.dolfinx.tri6.hrz_shares`:
a straight planar cell 1/19 at a corner, 16/57 at an edge node; axisymmetric ones r-weighted, taken in the
reference configuration as the masses are). A uniform force density then accelerates every node at f / rho, as
it does the continuum; the consistent weights ∫ N_a w dA (a planar corner 0, an edge node 1/3) would leave the
corners behind and shake the cells. The shares sum to one (the ledger holds to round-off). Their first moment
is the cell's centroid in a planar cell (1/19 Σ corners + 16/57 Σ midpoints = Σ corners / 3): the force's moment
is kept. In axisymmetry the HRZ masses' first moment is not the ring's (∫ r w dA / ∫ w dA): the shares move a
cell's force's point of action by a small fraction of the cell (measured: tests/coupling/test_transfer_tri6.py),
the price of the uniform acceleration (both cannot hold with these masses).
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


def share_forces(cells: np.ndarray, cell_force: np.ndarray, shares: np.ndarray, n_nodes: int) -> np.ndarray:
    """Nodal forces (N), shape (n_nodes, d), of quadratic cells ``cells`` (nc, k: body node rows) carrying the
    forces ``cell_force`` (nc, d) N, shared out by ``shares``: (k,) for every cell alike or (nc, k) per cell."""
    cells = np.asarray(cells)
    shares = np.broadcast_to(shares, cells.shape)
    out = np.zeros((n_nodes, cell_force.shape[1]))
    idx = cells.ravel()
    for d in range(cell_force.shape[1]):
        out[:, d] = np.bincount(idx, weights=(cell_force[:, d, None] * shares).ravel(), minlength=n_nodes)
    return out


def density_on_cells(name: str, em_rows: np.ndarray, rows: np.ndarray, n_em_cells: int, f: np.ndarray) -> np.ndarray:
    """The force density (N/m³), (nc, d), on the EM cells ``em_rows`` of quadratic body ``name``'s cells, from ``f``
    (m, d) given on the EM cells ``rows`` of a mesh of ``n_em_cells``. ValueError if one of them has none."""
    pos = np.full(n_em_cells, -1, dtype=np.int64)
    pos[rows] = np.arange(len(rows))
    k = pos[em_rows]
    if np.any(k < 0):
        raise ValueError(f"body {name!r}: {int((k < 0).sum())} of its cells carry no force density")
    return f[k]


def body_forces(bodies, x_em: np.ndarray, em_tris: np.ndarray, rows: np.ndarray, f: np.ndarray, *,
                axisymmetric: bool, scale: float = 1.0) -> dict[str, np.ndarray]:
    """Nodal forces (N) per body of a force density held on EM triangles (the 2D counterpart of
    :func:`.transfer3d.body_forces`).

    Parameters
    ----------
    bodies : sequence
        The conductor bodies (:class:`~pulseform.orchestrator.mesh.shared.ConductorBody`: ``name``, ``body_to_em``;
        a six-node body also ``cells6``, ``shares``, ``em_rows`` and ``n_nodes``).
    x_em : ndarray (N, 2)
        The EM mesh's (moved) nodes, m.
    em_tris : int array (M, 3)
        The EM mesh's triangles.
    rows : int array (m,)
        The rows of ``em_tris`` that carry the force density (every triangle of the bodies).
    f : ndarray (m, 2)
        The force density on them, N/m³.
    axisymmetric : bool
        Rings (weight 2πr) or planar (per metre of depth).
    scale : float
        Planar: the depth (m) that multiplies the per-metre forces; 1 in axisymmetry.

    Returns
    -------
    dict
        Body name -> (n, 2) nodal forces on its rows: the consistent ∫ N_i f w dA on a linear body's shared nodes
        (:func:`cell_to_nodal_forces`), f V shared by a six-node cell's nodes as their HRZ masses (module
        docstring).
    """
    out = {}
    linear = [b for b in bodies if getattr(b, "cells6", None) is None]
    if linear:
        f_em = scale * cell_to_nodal_forces(x_em, em_tris[rows], f, axisymmetric=axisymmetric)
        out.update({b.name: f_em[b.body_to_em] for b in linear})
    for b in bodies:
        if getattr(b, "cells6", None) is None:
            continue
        v = scale * cell_volumes(x_em, em_tris[b.em_rows], axisymmetric=axisymmetric)
        force = density_on_cells(b.name, b.em_rows, rows, len(em_tris), f) * v[:, None]
        out[b.name] = share_forces(b.cells6, force, b.shares, b.n_nodes)
    return out
