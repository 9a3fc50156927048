"""Compiled per-cell fields for outputs and history rows (cell volumes, elastic energy density,
von Mises stress and its maxima, the nodal extremes of a history row) and the kinetic-energy sum,
rounded exactly as the numpy expressions they replace in :class:`~.body.Body`,
:class:`~.solver.ExplicitSolver` and the orchestrator's history rows (same operations, same order;
sums as numpy's ``mean`` / ``sum`` over three components and :func:`.reductions.np_sum`).

They run once per history row, where the numpy versions
cost ~0.35 ms per call on the corner-fill mesh (gathers into (n, 3, 2) temporaries).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from .reductions import np_sum

__all__ = ["cell_volumes", "elastic_energy_density", "von_mises", "von_mises_max", "j2_times_3_max",
           "nodal_extremes", "kinetic_sum"]


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


@numba.njit(cache=True)
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
def von_mises_max(stress: np.ndarray) -> float:
    """Largest von Mises stress (Pa) over the cells, as ``von_mises(stress).max()`` without the
    array (NaN if one is NaN, as numpy's ``max``; ``-inf`` for no cells, where numpy raises)."""
    best = -np.inf
    for e in range(stress.shape[0]):
        best = _max_nan(best, math.sqrt(1.5 * _pressure_and_dev_norm2(stress, e)[1]))
    return best


@numba.njit(cache=True)
def _max_nan(best: float, value: float) -> float:
    """max(best, value) as numpy's ``max`` reduces: a NaN sticks."""
    return value if best == best and not value <= best else best


@numba.njit(cache=True)
def j2_times_3_max(stress: np.ndarray, ss: np.ndarray) -> float:
    """Largest 3 J2 / 1.5 = s.s + s_xy^2 - tr^2 / 3 (Pa^2) over the cells, given
    ``ss = np.einsum("ij,ij->i", stress, stress)``, rounded as the numpy expression
    ``(ss + stress[:, 3] * stress[:, 3] - tr * tr / 3.0).max()``, tr = s_xx + s_yy + s_zz
    (NaN if one is NaN; ``-inf`` for no cells). The einsum stays in numpy: its summation order
    depends on the CPU's vector width."""
    best = -np.inf
    for e in range(stress.shape[0]):
        tr = stress[e, 0] + stress[e, 1] + stress[e, 2]
        best = _max_nan(best, (ss[e] + stress[e, 3] * stress[e, 3]) - tr * tr / 3.0)
    return best


@numba.njit(cache=True)
def nodal_extremes(x: np.ndarray, X0: np.ndarray, v: np.ndarray, n: int) -> tuple[float, float, float]:
    """Largest |u_x| (m), |u_y| (m) of the displacement u = x - X0 and largest |v| (m/s) over the
    nodes i < n, as numpy's ``np.abs(u[:n, 0]).max()``, ``np.abs(u[:n, 1]).max()``,
    ``np.sqrt((v[:n] ** 2).sum(axis=1)).max()`` (NaN if one is NaN; ``-inf`` for no nodes)."""
    ux = -np.inf
    uy = -np.inf
    sp = -np.inf
    for i in range(n):
        ux = _max_nan(ux, abs(x[i, 0] - X0[i, 0]))
        uy = _max_nan(uy, abs(x[i, 1] - X0[i, 1]))
        sp = _max_nan(sp, math.sqrt(v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1]))
    return ux, uy, sp


@numba.njit(cache=True)
def kinetic_sum(mass: np.ndarray, v: np.ndarray, a: np.ndarray, hdt: float, n: int,
                scratch: np.ndarray) -> float:
    """sum over nodes i < n of m_i |v_i + hdt a_i|^2 (kg m^2/s^2; 2 or 3 components), as
    ``np.sum(m * np.sum((v + hdt * a) ** 2, axis=1))``; ``scratch`` holds >= n floats."""
    for i in range(n):
        w0 = v[i, 0] + hdt * a[i, 0]
        w1 = v[i, 1] + hdt * a[i, 1]
        s = w0 * w0 + w1 * w1
        for c in range(2, v.shape[1]):     # 3D bodies
            w = v[i, c] + hdt * a[i, c]
            s += w * w
        scratch[i] = mass[i] * s
    return np_sum(scratch, n)
