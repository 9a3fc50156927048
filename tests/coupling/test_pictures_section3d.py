"""The sections of the 3D bodies (orchestrator/run/pictures_section3d.py), without a run: a unit cube of
tetrahedra (6 per cell of a 3 x 3 x 3 grid) cut by planes; reference: the cube's cross-section, area 1 m^2
whatever the plane's position, and the area of its faces on a bounding plane (1 m^2)."""
import numpy as np
import pytest

from pulseform.orchestrator.run.pictures_section3d import cut_tets, plane_faces


def _cube(n: int = 3):
    g = np.linspace(0.0, 1.0, n + 1)
    pts = np.array([(x, y, z) for x in g for y in g for z in g])
    idx = lambda i, j, k: (i * (n + 1) + j) * (n + 1) + k
    tets = []
    for i in range(n):
        for j in range(n):
            for k in range(n):
                c = [idx(i + a, j + b, k + d) for a in (0, 1) for b in (0, 1) for d in (0, 1)]
                # Kuhn's 6 tetrahedra of the cell along its diagonal c[0] - c[7]
                for p in ((1, 3), (1, 5), (2, 3), (2, 6), (4, 5), (4, 6)):
                    tets.append([c[0], c[p[0]], c[p[1]], c[7]])
    return pts, np.array(tets)


def _area(x: np.ndarray, tris: np.ndarray) -> float:
    p = x[tris]
    return float(0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum())


@pytest.mark.parametrize("axis, value", [(0, 0.5), (1, 0.2), (2, 1 / 3), (1, 2 / 3)])
def test_a_plane_through_the_cube_cuts_its_cross_section(axis, value):
    pts, tets = _cube()
    edges, w, tris, owner = cut_tets(pts, tets, axis, value)
    x = (1 - w[:, None]) * pts[edges[:, 0]] + w[:, None] * pts[edges[:, 1]]
    assert np.abs(x[:, axis] - value).max() < 1e-15
    assert _area(x, tris) == pytest.approx(1.0, rel=1e-12)
    assert owner.max() < len(tets)
    # each triangle's normal along the axis: no folded (zero-area or overlapping) pieces
    p = x[tris]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert np.all(np.abs(n[:, axis]) > 0)


def test_the_faces_on_a_bounding_plane():
    pts, tets = _cube()
    faces, owner = plane_faces(pts, tets, 1, 0.0)
    assert _area(pts, faces) == pytest.approx(1.0, rel=1e-12) and len(faces) == 18
    assert np.all(np.isin(faces, tets[owner]))
    # cut there, the cube gives the same faces (a face on the plane taken once)
    edges, w, tris, _ = cut_tets(pts, tets, 1, 0.0)
    assert np.all(w == 0) and np.all(edges[:, 0] == edges[:, 1])
    assert sorted(map(sorted, edges[tris, 0].tolist())) == sorted(map(sorted, faces.tolist()))
