"""Per-cell quantities of P1 tetrahedra for the fields and the energy ledger (the 3D twin of
:mod:`.cell_fields`): signed volumes, elastic energy density and von Mises stress, compiled."""
from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["tet_volumes", "tet_elastic_energy_density", "tet_von_mises"]


@numba.njit(cache=True)
def tet_volumes(cells: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Current (signed) volumes of the tetrahedra, m^3."""
    n = cells.shape[0]
    out = np.empty(n)
    for e in range(n):
        i0 = cells[e, 0]
        ax = x[cells[e, 1], 0] - x[i0, 0]
        ay = x[cells[e, 1], 1] - x[i0, 1]
        az = x[cells[e, 1], 2] - x[i0, 2]
        bx = x[cells[e, 2], 0] - x[i0, 0]
        by = x[cells[e, 2], 1] - x[i0, 1]
        bz = x[cells[e, 2], 2] - x[i0, 2]
        cx = x[cells[e, 3], 0] - x[i0, 0]
        cy = x[cells[e, 3], 1] - x[i0, 1]
        cz = x[cells[e, 3], 2] - x[i0, 2]
        out[e] = (ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz)
                  + az * (bx * cy - by * cx)) / 6.0
    return out


@numba.njit(cache=True)
def tet_elastic_energy_density(stress: np.ndarray, G: float, K: float) -> np.ndarray:
    """Elastic energy per unit volume, s:s / 4G + p^2 / 2K, J/m^3, of 6-component stresses (Pa)."""
    n = stress.shape[0]
    out = np.empty(n)
    for e in range(n):
        p = (stress[e, 0] + stress[e, 1] + stress[e, 2]) / 3.0
        d0 = stress[e, 0] - p
        d1 = stress[e, 1] - p
        d2 = stress[e, 2] - p
        ss = (d0 * d0 + d1 * d1 + d2 * d2
              + 2.0 * (stress[e, 3] ** 2 + stress[e, 4] ** 2 + stress[e, 5] ** 2))
        out[e] = ss / (4.0 * G) + p * p / (2.0 * K)
    return out


@numba.njit(cache=True)
def tet_von_mises(stress: np.ndarray) -> np.ndarray:
    """Von Mises stress sqrt(3/2 s:s) of 6-component stresses, Pa."""
    n = stress.shape[0]
    out = np.empty(n)
    for e in range(n):
        p = (stress[e, 0] + stress[e, 1] + stress[e, 2]) / 3.0
        d0 = stress[e, 0] - p
        d1 = stress[e, 1] - p
        d2 = stress[e, 2] - p
        out[e] = math.sqrt(1.5 * (d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * (
            stress[e, 3] ** 2 + stress[e, 4] ** 2 + stress[e, 5] ** 2)))
    return out
