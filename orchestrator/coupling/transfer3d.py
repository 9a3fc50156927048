"""Transfer of 3D EM loads onto the mechanical tetrahedra: nodal forces and their ledger.

Linear bodies (four-node tetrahedra on the EM mesh's nodes): for a force density f_e (N/m^3) constant on a
tetrahedron of volume V_e, the consistent nodal force of each of its four nodes is f_e ∫ N_i dV = f_e V_e / 4,
so Σ_i F_i = Σ_e f_e V_e to round-off (partition of unity): the transfer is conservative by construction, and
the loop's ledger checks it every EM step (:func:`.transfer.ledger_error`).

Ten-node bodies (``element = "tet10"``, :mod:`pulseform.solvers.dolfinx.tet10`: the EM mesh's vertices first,
then one node per edge): the cell's force f_e V_e goes to its ten nodes in the proportions of their HRZ lumped
masses (:data:`TEN_NODE_SHARES`: a corner 1/36, an edge node 4/27). A uniform force density then gives every node
the same acceleration f / rho, as it gives the continuum; the consistent quadratic weights (a corner -1/20, an
edge node 1/5) would pull the corners against the force and shake the cells (measured:
tests/coupling/test_3d_transfer_tet10.py). The shares sum to one (Σ F_i = Σ f_e V_e: the ledger holds) and their
first moment is the cell's centroid (Σ_i s_i x_i = (1/36 + 3/2 · 4/27) Σ corners = the centroid of the straight
cell): the force's moment is kept too.
"""

from __future__ import annotations

import numpy as np

from pulseform.solvers.dolfinx.tet10 import HRZ_SHARES
from pulseform.solvers.getdp.mesh3d import tet_volumes

from .transfer import density_on_cells, share_forces

#: the share of a ten-node cell's force on its nodes (corners 0-3, then edge nodes 4-9): the HRZ mass proportions
TEN_NODE_SHARES = HRZ_SHARES


def tet_nodal_forces(x: np.ndarray, cells: np.ndarray, f_cell: np.ndarray) -> np.ndarray:
    """Consistent nodal forces (N), shape (N, 3), of a per-cell force density ``f_cell`` (M, 3) N/m^3."""
    w = tet_volumes(x, cells) / 4.0
    out = np.zeros((x.shape[0], 3))
    idx = cells.ravel()
    for d in range(3):
        out[:, d] = np.bincount(idx, weights=np.repeat(w * f_cell[:, d], 4), minlength=x.shape[0])
    return out


def tet_force_integral(x: np.ndarray, cells: np.ndarray, f_cell: np.ndarray) -> np.ndarray:
    """∫ f dV = Σ_e f_e V_e (N), shape (3,)."""
    return (f_cell * tet_volumes(x, cells)[:, None]).sum(axis=0)


def ten_node_forces(cells10: np.ndarray, cell_force: np.ndarray, n_nodes: int,
                    shares: np.ndarray = TEN_NODE_SHARES) -> np.ndarray:
    """Nodal forces (N), shape (n_nodes, 3), of ten-node cells that carry the forces ``cell_force`` (nc, 3) N
    (f_e V_e), shared out by ``shares`` (10,) (default the HRZ mass proportions, module docstring;
    :func:`.transfer.share_forces`)."""
    return share_forces(cells10, cell_force, shares, n_nodes)


def body_forces(bodies, x_em: np.ndarray, em_tets: np.ndarray, rows: np.ndarray, f: np.ndarray) -> dict[str, np.ndarray]:
    """Nodal forces (N) per body of a force density held on EM tetrahedra.

    Parameters
    ----------
    bodies : sequence
        The conductor bodies (:class:`~pulseform.orchestrator.em.participant3d.ConductorBody3D`: ``name``,
        ``body_to_em``; a ten-node body also ``cells10``, ``em_rows`` and ``n_nodes``).
    x_em : ndarray (N, 3)
        The EM mesh's (moved) nodes, m.
    em_tets : int array (M, 4)
        The EM mesh's tetrahedra.
    rows : int array (m,)
        The rows of ``em_tets`` that carry the force density (every tetrahedron of the bodies).
    f : ndarray (m, 3)
        The force density on them, N/m^3.

    Returns
    -------
    dict
        Body name -> (n, 3) nodal forces on its rows: f V / 4 on the shared nodes of a linear body
        (:func:`tet_nodal_forces`), the HRZ shares of f V on a ten-node body's nodes (:func:`ten_node_forces`).
    """
    out = {}
    linear = [b for b in bodies if getattr(b, "cells10", None) is None]
    if linear:
        f_em = tet_nodal_forces(x_em, em_tets[rows], f)
        out.update({b.name: f_em[b.body_to_em] for b in linear})
    for b in bodies:
        if getattr(b, "cells10", None) is None:
            continue
        force = density_on_cells(b.name, b.em_rows, rows, len(em_tets), f) \
            * tet_volumes(x_em, em_tets[b.em_rows])[:, None]
        out[b.name] = ten_node_forces(b.cells10, force, b.n_nodes)
    return out
