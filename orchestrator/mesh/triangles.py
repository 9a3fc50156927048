"""P1 triangle helpers shared by the meshes and the transfer: signed areas, oriented boundary edges."""

from __future__ import annotations

import numpy as np


def triangle_areas(x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Signed areas (m²) of triangles; positive for counter-clockwise node order."""
    a, b, c = x[cells[:, 0]], x[cells[:, 1]], x[cells[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1]))


def boundary_facets(cells: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Boundary edges (K, 2) oriented with the body on their left (counter-clockwise boundary)."""
    c = cells.copy()
    neg = triangle_areas(x, c) < 0
    c[neg] = c[neg][:, [0, 2, 1]]
    edges = np.concatenate([c[:, [0, 1]], c[:, [1, 2]], c[:, [2, 0]]])
    key = np.sort(edges, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return edges[counts[inverse] == 1]


def region_surface(points: np.ndarray, triangles: np.ndarray, axisymmetric: bool) -> float:
    """Outer surface (m²; per metre of depth in planar) of the triangles ``triangles`` (node rows of ``points``):
    their :func:`boundary_facets`, times 2π r at each edge's midpoint in axisymmetry."""
    tri = np.asarray(triangles, np.int64)
    if len(tri) == 0:
        return 0.0
    p = np.asarray(points, float)
    edges = boundary_facets(tri, p)
    a, b = p[edges[:, 0]], p[edges[:, 1]]
    length = np.linalg.norm(b - a, axis=1)
    if axisymmetric:
        return float(np.sum(np.pi * (a[:, 0] + b[:, 0]) * length))
    return float(length.sum())
