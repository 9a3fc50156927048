"""A checkerboard index of a cell field on tetrahedra: how much each cell's value departs from those of its face
neighbours, relative to the field itself (issue 34 item 4: the linear tetrahedra's plastic strain in a bent sheet
alternates from cell to cell; the ten-node cells' does not).

For the cells e of a region R (e.g. the plastically strained cells) with values p_e and volumes V_e, and the
volume-weighted mean of the values of e's face neighbours (all of them, in R or not)
p̄_e = Σ_{f ~ e} V_f p_f / Σ_{f ~ e} V_f::

    index = sqrt(Σ_R V_e (p_e - p̄_e)^2 / Σ_R V_e) / sqrt(Σ_R V_e p_e^2 / Σ_R V_e)

A smooth field on a mesh of size h departs from its neighbours' mean by O(h |∇p|) at most (less where the
neighbours surround the cell), so the index of a resolved field is small and falls at least as h when the mesh is
refined (a linear field on structured tetrahedra: 0.015, 0.0056, 0.0021 for h = 1/4, 1/8, 1/16,
tests/mechanics/test_checkerboard.py); a field that alternates between neighbours gives an index of order one
whatever h (0.5 for values 1 ± 1/2 of a smooth field, the sign random per cell).
"""

from __future__ import annotations

import numpy as np

from pulseform.solvers.getdp.mesh3d import tet_volumes

__all__ = ["face_neighbours", "checkerboard_index"]


def face_neighbours(tets: np.ndarray) -> np.ndarray:
    """The pairs (m, 2) of tetrahedra (rows of ``tets`` (nc, 4)) that share a face."""
    tets = np.asarray(tets, dtype=np.int64)
    faces = np.sort(tets[:, [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]].reshape(-1, 3), axis=1)
    owner = np.repeat(np.arange(len(tets)), 4)
    order = np.lexsort(faces.T[::-1])
    faces, owner = faces[order], owner[order]
    same = np.all(faces[1:] == faces[:-1], axis=1)
    return np.column_stack([owner[:-1][same], owner[1:][same]])


def checkerboard_index(points: np.ndarray, tets: np.ndarray, values: np.ndarray,
                       region: np.ndarray | None = None) -> float:
    """The checkerboard index (module docstring), dimensionless.

    Parameters
    ----------
    points : ndarray (N, 3)
        Node positions, m (the reference ones: the weights are volumes).
    tets : int array (nc, 4)
        Tetrahedra (a ten-node cell's corners).
    values : ndarray (nc,)
        The cell field (e.g. the equivalent plastic strain, a ten-node cell's Gauss-point mean).
    region : bool array (nc,), optional
        The cells the index is taken over (default: those with a positive value).

    Returns
    -------
    float
        The index; NaN when the region is empty or the field is zero on it.
    """
    values = np.asarray(values, dtype=float)
    region = values > 0.0 if region is None else np.asarray(region, dtype=bool)
    vol = tet_volumes(np.asarray(points, dtype=float), np.asarray(tets))
    pairs = face_neighbours(tets)
    a, b = np.concatenate([pairs[:, 0], pairs[:, 1]]), np.concatenate([pairs[:, 1], pairs[:, 0]])
    n = len(values)
    weight = np.bincount(a, weights=vol[b], minlength=n)
    mean = np.bincount(a, weights=vol[b] * values[b], minlength=n) / np.where(weight > 0, weight, 1.0)
    on = region & (weight > 0)
    field = float(np.sum(vol[on] * values[on] ** 2))
    if not on.any() or field == 0.0:
        return float("nan")
    return float(np.sqrt(np.sum(vol[on] * (values[on] - mean[on]) ** 2) / field))
