"""A thin sector of an axisymmetric part (a coupled 3D sector case, ``[sector]``) in the mechanics
pictures: its meridian face θ = 0 (the symmetry plane y = 0) as an (r, z) section, which
:mod:`.pictures_mech` revolves about z like an axisymmetric body's mesh, so that a 1.25° sector is
seen as the bulged sheet it stands for rather than as a sliver."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np

from .pictures_solid import boundary_faces


def sector_angle(results_dir: Path) -> float | None:
    """The ``[sector] angle_deg`` of the results folder's resolved case (None: not a sector case)."""
    try:
        data = tomllib.loads((Path(results_dir) / "case.toml").read_text())
    except (OSError, ValueError):
        return None
    angle = data.get("sector", {}).get("angle_deg") if isinstance(data.get("sector"), dict) else None
    return float(angle) if angle else None


class MeridianSection:
    """The exterior faces of a sector body's tetrahedra on the plane y = 0 (reference coordinates), as
    a triangulation of the (r, z) section.

    Attributes
    ----------
    nodes : ndarray (n,)
        The body's nodes on the section (rows of its points).
    triangles : ndarray (m, 3)
        Section triangles as rows of ``nodes``.
    owner : ndarray (m,)
        The tetrahedron each triangle is a face of (its cell values colour the triangle).
    """

    def __init__(self, points: np.ndarray, tets: np.ndarray) -> None:
        faces, owner = boundary_faces(tets)
        scale = max(float(np.abs(points).max()), 1e-30)
        on_plane = np.abs(points[faces, 1]).max(axis=1) <= 1e-9 * scale
        if not on_plane.any():
            raise ValueError("no exterior face of the body lies on the sector's plane y = 0")
        faces, self.owner = faces[on_plane], owner[on_plane]
        self.nodes, inverse = np.unique(faces, return_inverse=True)
        self.triangles = inverse.reshape(-1, 3)

    def points2(self, x: np.ndarray) -> np.ndarray:
        """(r, z) of the section's nodes at node positions ``x`` (N, 3), in the units of ``x``."""
        p = x[self.nodes]
        return np.column_stack([np.hypot(p[:, 0], p[:, 1]), p[:, 2]])
