"""Soft contact, eq. (5), of 3D bodies' boundary nodes with a rigid plane (issue 20, the simplest
part of deliverable 2): p = k (1/h - 1/h0) for 0 < h < h0, h the node's distance to the plane,
pushing along the plane's normal; the force on a node is p A n with A its boundary area
projected on the plane (:meth:`~.body3d.Body3D.wall_tributary_areas`). No friction, no viscous
term, no deformable master yet.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import numpy as np

__all__ = ["SoftPlaneSpec", "soft_plane_forces"]

@dataclass(frozen=True)
class SoftPlaneSpec:
    """A rigid plane {(x - point) . normal = 0} with the paper's soft contact layer, eq. (5).

    Parameters
    ----------
    point : (float, float, float)
        A point of the plane, m.
    normal : (float, float, float)
        Normal pointing to the bodies' side (normalised internally).
    stiffness : float
        k, Pa m (force per unit area times length, as in :class:`~.contact.ContactPairSpec`).
    h0 : float
        Layer width, m: contact acts for h < h0.
    bodies : sequence of str, optional
        Bodies it acts on (default: all).
    """

    point: tuple
    normal: tuple
    stiffness: float
    h0: float
    bodies: Optional[Sequence[str]] = None

    def __post_init__(self) -> None:
        if np.asarray(self.point).shape != (3,) or np.asarray(self.normal).shape != (3,):
            raise ValueError("SoftPlaneSpec needs a 3-component point and normal")
        if not (self.stiffness > 0 and self.h0 > 0):
            raise ValueError("SoftPlaneSpec needs stiffness > 0 and h0 > 0")
        if not np.linalg.norm(np.asarray(self.normal, float)) > 0:
            raise ValueError("SoftPlaneSpec.normal must be non-zero")

    def unit_normal(self) -> np.ndarray:
        """The normal, normalised."""
        n = np.asarray(self.normal, dtype=float)
        return n / np.linalg.norm(n)


def soft_plane_forces(plane: SoftPlaneSpec, x: np.ndarray, area: np.ndarray
                      ) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Eq. (5) against ``plane`` for nodes at ``x`` (N, 3) with plane-facing areas ``area`` (N,).

    Returns
    -------
    rows : int array
        Nodes in the layer (h < h0 and area > 0).
    h : array
        Their distances to the plane, m (h <= 0 means penetration: the caller raises).
    p : array
        Contact stress k (1/h - 1/h0), Pa.
    force : (len(rows), 3) array
        p A n, N.
    stored : array
        Layer energy per node A k (ln(h0/h) - (h0 - h)/h0), J (the integral of eq. (5) over h).
    """
    n = plane.unit_normal()
    h_all = (x - np.asarray(plane.point, float)) @ n
    rows = np.flatnonzero((h_all < plane.h0) & (area > 0.0))
    h = h_all[rows]
    k, h0 = plane.stiffness, plane.h0
    with np.errstate(divide="ignore", invalid="ignore"):
        p = k * (1.0 / h - 1.0 / h0)
        stored = area[rows] * k * (np.log(h0 / h) - (h0 - h) / h0)
    return rows, h, p, (p * area[rows])[:, None] * n, stored
