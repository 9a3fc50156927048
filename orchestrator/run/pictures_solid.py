"""The 3D bodies (tetrahedra, ``formulation = "3d"``) in the mechanics pictures of :mod:`.pictures_mech`:
the exterior surface of the deformed tetrahedra, each face coloured by its cell's value, seen from
a 3/4 view (from +x, -y, +z: a quarter model in y, z >= 0 shows its symmetry plane y = 0)."""

from __future__ import annotations

import numpy as np

#: the four faces of a tetrahedron (node positions in the cell)
_TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])
#: camera direction of the 3D view (from the centre towards the camera), normalised below
VIEW = np.array([1.0, -1.6, 1.1])


def boundary_faces(tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Faces (F, 3) of the tetrahedra ``tets`` (C, 4) that belong to one cell only, and that cell's
    index (F,)."""
    faces = tets[:, _TET_FACES].reshape(-1, 3)
    owner = np.repeat(np.arange(len(tets)), 4)
    key = np.sort(faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    once = counts[inverse.ravel()] == 1
    return faces[once], owner[once]


def solid_surface(points3: np.ndarray, faces: np.ndarray, owner: np.ndarray, values: np.ndarray):
    """(points (N, 3), pyvista face list, per-face values) of the body's exterior surface at node
    positions ``points3`` (mm), ``values`` per cell."""
    flat = np.column_stack([np.full(len(faces), 3), faces]).ravel()
    return points3, flat, values[owner]


def solid_camera(plotter, bounds) -> None:
    """Isometric 3/4 view of ``bounds`` (xmin, xmax, ymin, ymax, zmin, zmax), z up."""
    xmin, xmax, ymin, ymax, zmin, zmax = bounds
    centre = np.array([(xmin + xmax) / 2, (ymin + ymax) / 2, (zmin + zmax) / 2])
    size = max(xmax - xmin, ymax - ymin, zmax - zmin, 1e-9)
    d = VIEW / np.linalg.norm(VIEW)
    plotter.camera_position = [tuple(centre + 3.0 * size * d), tuple(centre), (0.0, 0.0, 1.0)]
    plotter.reset_camera(bounds=bounds)
    plotter.camera.zoom(1.3)
