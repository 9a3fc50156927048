"""A wedge model in the mechanics pictures (:mod:`.pictures_mech`): a 3D model between two ``[[symmetry]]``
planes through the z-axis (a sector of a ring coil and sheet, a quarter model) is drawn unfolded by its own
symmetry over 270° about z and seen from the open quarter, as an axisymmetric model is drawn revolved, so that
a 1.25° sector shows the bulged sheet it stands for rather than a sliver.

The two mirror planes at angle α generate the device from the wedge: copy k covers [kα, (k+1)α], the wedge
turned by kα for even k, mirrored in its first plane and turned by (k+1)α for odd k (the field of a mirror
plane is symmetric about it). Each copy draws the body's exterior faces but those on the planes (inside the
device), except the open cuts at 0° and at the last copy's far plane. Exact for any device with that
symmetry (not only an axisymmetric one); values per cell are carried to the copies.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .pictures_solid import boundary_faces

#: the angle the unfolded wedge covers (degrees), as an axisymmetric model is revolved
UNFOLD_DEG = 270.0


def wedge_planes(results_dir: Path) -> list[np.ndarray] | None:
    """The unit normals of the two ``[[symmetry]]`` planes of the results folder's resolved case when they both
    contain the z-axis (a wedge about z) in a 3D case; None otherwise (no case file, another plane set)."""
    try:
        data = tomllib.loads((Path(results_dir) / "case.toml").read_text())
    except (OSError, ValueError):
        return None
    mech = data.get("mechanics")
    sym = data.get("symmetry")
    if not isinstance(mech, dict) or mech.get("formulation") != "3d" or not isinstance(sym, list) or len(sym) != 2:
        return None
    normals = []
    for s in sym:
        try:
            n = np.asarray(s["normal"], dtype=float)
            p = np.asarray(s.get("point", (0.0, 0.0, 0.0)), dtype=float)
        except (KeyError, TypeError, ValueError):
            return None
        if n.shape != (3,) or p.shape != (3,) or not np.linalg.norm(n) > 0:
            return None
        n = n / np.linalg.norm(n)
        if abs(n[2]) > 1e-12 or abs(float(n @ p)) > 1e-12 * max(1.0, float(np.abs(p).max())):
            return None   # the plane does not contain the z-axis
        normals.append(n)
    if abs(float(np.cross(normals[0], normals[1])[2])) <= 1e-12:
        return None   # parallel planes: a slab, not a wedge
    return normals


@dataclass
class Wedge:
    """The wedge between two planes through the z-axis, on the side of ``points`` (module docstring).

    Attributes
    ----------
    e1, e2 : ndarray (3,)
        Unit vectors in the xy-plane: ``e1`` along the first plane (towards the wedge), ``e2`` turned by 90°
        towards the second; a point's angle in the wedge is atan2(x·e2, x·e1) in [0, ``angle``].
    angle : float
        The wedge's angle (rad).
    normals : list of ndarray
        The planes' unit normals.
    """

    e1: np.ndarray
    e2: np.ndarray
    angle: float
    normals: list

    @classmethod
    def of(cls, normals: list[np.ndarray], points: np.ndarray) -> "Wedge":
        """The wedge of the planes (unit ``normals``, through the z-axis) that holds ``points`` (N, 3)."""
        c = np.asarray(points, float)[:, :2].mean(axis=0)
        if not np.linalg.norm(c) > 0:
            raise ValueError("the bodies' centroid lies on the z-axis: not a wedge about it")
        rays = []
        for n in normals:
            d = np.array([-n[1], n[0]])   # along the plane, normal to z
            rays.append(d if d @ c >= 0 else -d)
        cross = rays[0][0] * rays[1][1] - rays[0][1] * rays[1][0]
        e1 = np.array([rays[0][0], rays[0][1], 0.0])
        e2 = math.copysign(1.0, cross) * np.array([-e1[1], e1[0], 0.0])
        angle = math.atan2(abs(cross), float(rays[0] @ rays[1]))
        return cls(e1, e2, angle, list(normals))

    @property
    def copies(self) -> int:
        """Copies drawn: enough to cover :data:`UNFOLD_DEG`."""
        return max(1, math.ceil(math.radians(UNFOLD_DEG) / self.angle - 1e-9))

    def transform(self, k: int) -> np.ndarray:
        """The 3x3 map of copy ``k`` (module docstring): x' = T x."""
        q = np.column_stack([self.e1, self.e2, [0.0, 0.0, 1.0]])
        theta = (k + (k % 2)) * self.angle
        c, s = math.cos(theta), math.sin(theta)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        mirror = np.diag([1.0, -1.0 if k % 2 else 1.0, 1.0])
        return q @ rot @ mirror @ q.T


class UnfoldedBody:
    """One body of a wedge model, unfolded (module docstring): its exterior faces sorted into those on the first
    plane, on the second plane and elsewhere (reference coordinates).

    Attributes
    ----------
    faces : list of ndarray (F_i, 3)
        Node rows of the faces off the planes (0), on the first plane (1), on the second plane (2).
    owner : list of ndarray (F_i,)
        The tetrahedron each face belongs to.
    """

    def __init__(self, wedge: Wedge, points: np.ndarray, tets: np.ndarray) -> None:
        self.wedge = wedge
        faces, owner = boundary_faces(tets)
        scale = max(float(np.abs(points).max()), 1e-30)
        on = [np.abs(points[faces] @ n).max(axis=1) <= 1e-9 * scale for n in wedge.normals]
        off = ~(on[0] | on[1])
        first, second = on[0], on[1] & ~on[0]
        self.faces = [faces[off], faces[first], faces[second]]
        self.owner = [owner[off], owner[first], owner[second]]

    def surface(self, x: np.ndarray, values: np.ndarray):
        """(points (P, 3), pyvista face list, per-face values) of the unfolded body at node positions ``x``
        (N, 3) (any length unit), ``values`` per cell."""
        n, m = len(x), self.wedge.copies
        pts, flat, vals = [], [], []
        for k in range(m):
            pts.append(x @ self.wedge.transform(k).T)
            parts = [0]
            if k == 0:
                parts.append(1)   # the open cut at 0
            if k == m - 1:
                parts.append(1 if k % 2 else 2)   # the far plane of the last copy
            for j in parts:
                f = self.faces[j] if k % 2 == 0 else self.faces[j][:, ::-1]   # a mirror turns the faces over
                flat.append(np.column_stack([np.full(len(f), 3), f + k * n]).ravel())
                vals.append(values[self.owner[j]])
        return np.vstack(pts), np.concatenate(flat), np.concatenate(vals)
