"""Transfer of 3D EM loads onto the mechanical tetrahedra: consistent nodal forces and their ledger.

For a force density f_e (N/m^3) constant on a linear tetrahedron of volume V_e, the consistent
nodal force of each of its four nodes is f_e ∫ N_i dV = f_e V_e / 4, so Σ_i F_i = Σ_e f_e V_e to
round-off (partition of unity): the transfer is conservative by construction, and the loop's
ledger checks it every EM step (:func:`.transfer.ledger_error`).
"""

from __future__ import annotations

import numpy as np

from pulseform.solvers.getdp.mesh3d import tet_volumes


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
