"""Compiled per-cell fields for outputs and history rows (cell volumes, elastic energy density,
von Mises stress) and the kinetic-energy sum, rounded exactly as the numpy expressions they
replace in :class:`~.body.Body` and :class:`~.solver.ExplicitSolver` (same operations, same
order; sums as numpy's ``mean`` / ``sum`` over three components and :func:`.reductions.np_sum`).

They run once per history row (twice with the corner-fill analysis), where the numpy versions
cost ~0.35 ms per call on the corner-fill mesh (gathers into (n, 3, 2) temporaries).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from .reductions import np_sum

__all__ = ["cell_volumes", "elastic_energy_density", "von_mises", "kinetic_sum"]


@numba.njit(cache=True)
def cell_volumes(cells: np.ndarray, x: np.ndarray, axisymmetric: bool,
                 thickness: float) -> np.ndarray:
    """Current cell volumes, m^3 (planar: area x thickness; axisymmetric: 2 pi r_c area)."""
    n = cells.shape[0]
    out = np.empty(n)
    twopi = 2 * np.pi
    for e in range(n):
        i0 = cells[e, 0]
        i1 = cells[e, 1]
        i2 = cells[e, 2]
        a = 0.5 * ((x[i1, 0] - x[i0, 0]) * (x[i2, 1] - x[i0, 1])
                   - (x[i2, 0] - x[i0, 0]) * (x[i1, 1] - x[i0, 1]))
        if axisymmetric:
            out[e] = twopi * ((x[i0, 0] + x[i1, 0] + x[i2, 0]) / 3.0) * a
        else:
            out[e] = thickness * a
    return out


@numba.njit(cache=True, inline="always")
def _pressure_and_dev_norm2(stress: np.ndarray, e: int) -> tuple[float, float]:
    """Mean stress p (Pa) of cell ``e`` and s:s (Pa^2) of its deviator (xx, yy, zz, xy components),
    summed in the order of the numpy code it replaced (same bits)."""
    p = (stress[e, 0] + stress[e, 1] + stress[e, 2]) / 3.0
    d0 = stress[e, 0] - p
    d1 = stress[e, 1] - p
    d2 = stress[e, 2] - p
    dd = d0 * d0 + d1 * d1 + d2 * d2
    return p, dd + 2 * (stress[e, 3] * stress[e, 3])


@numba.njit(cache=True)
def elastic_energy_density(stress: np.ndarray, G: float, K: float) -> np.ndarray:
    """Elastic energy per unit volume of each cell, s:s / 4G + p^2 / 2K, J/m^3 (stress in Pa)."""
    n = stress.shape[0]
    out = np.empty(n)
    g4 = 4 * G
    k2 = 2 * K
    for e in range(n):
        p, ss = _pressure_and_dev_norm2(stress, e)
        out[e] = ss / g4 + (p * p) / k2
    return out


@numba.njit(cache=True)
def von_mises(stress: np.ndarray) -> np.ndarray:
    """Von Mises stress of each cell, Pa."""
    n = stress.shape[0]
    out = np.empty(n)
    for e in range(n):
        out[e] = math.sqrt(1.5 * _pressure_and_dev_norm2(stress, e)[1])
    return out


@numba.njit(cache=True)
def kinetic_sum(mass: np.ndarray, v: np.ndarray, a: np.ndarray, hdt: float, n: int,
                scratch: np.ndarray) -> float:
    """sum over nodes i < n of m_i |v_i + hdt a_i|^2 (kg m^2/s^2), as
    ``np.sum(m * np.sum((v + hdt * a) ** 2, axis=1))``; ``scratch`` holds >= n floats."""
    for i in range(n):
        w0 = v[i, 0] + hdt * a[i, 0]
        w1 = v[i, 1] + hdt * a[i, 1]
        scratch[i] = mass[i] * (w0 * w0 + w1 * w1)
    return np_sum(scratch, n)
