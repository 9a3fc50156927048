"""Node markers of the case file's selectors (DOLFINx-style: callables on coordinates of shape (3, N) that give a
bool per node): a ``Box`` (x, y bounds; in 3D also z and the distance from the z-axis) and a set of points (the
nodes of a physical surface group)."""

from __future__ import annotations

from typing import Callable

import numpy as np
from scipy.spatial import cKDTree


def box_marker(box, tol: float = 0.0) -> Callable[[np.ndarray], np.ndarray]:
    """The nodes inside ``box`` (a case-file :class:`~..case.parts.Box`; inclusive, widened by ``tol`` m): its
    bounds in x and y, and in 3D cases z and the distance sqrt(x² + y²) from the z-axis."""
    def inside(x: np.ndarray) -> np.ndarray:
        out = ((x[0] >= box.xmin - tol) & (x[0] <= box.xmax + tol) & (x[1] >= box.ymin - tol)
               & (x[1] <= box.ymax + tol))
        if box.has_z():
            r = np.hypot(x[0], x[1])
            out &= (x[2] >= box.zmin - tol) & (x[2] <= box.zmax + tol) & (r >= box.rmin - tol) & (r <= box.rmax + tol)
        return out
    return inside


def points_marker(points: np.ndarray, tol: float) -> Callable[[np.ndarray], np.ndarray]:
    """The nodes within ``tol`` (m) of one of ``points`` (n, 3) (e.g. a surface group's nodes)."""
    tree = cKDTree(points)
    return lambda x: tree.query(np.asarray(x).T, distance_upper_bound=tol)[0] <= tol
