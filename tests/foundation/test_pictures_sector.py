"""The meridian section of a sector body (orchestrator/run/pictures_sector.py), which the mechanics
pictures revolve about z for a coupled 3D sector case."""

import numpy as np
import pytest

from pulseform.orchestrator.run.pictures_sector import MeridianSection, sector_angle

#: the six tetrahedra of a unit cube (Kuhn split: all around the diagonal from corner 0 to corner 7)
_KUHN = np.array([[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]])


def _box_tets(nx: int, ny: int, nz: int, size=(1.0, 0.1, 0.2)):
    """A structured tetrahedral mesh of [0, a] x [0, b] x [0, c] (conforming Kuhn cubes)."""
    g = [np.linspace(0.0, s, n + 1) for s, n in zip(size, (nx, ny, nz))]
    X, Y, Z = np.meshgrid(*g, indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
    idx = np.arange(len(pts)).reshape(nx + 1, ny + 1, nz + 1)
    cells = []
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                c = [idx[i + di, j + dj, k + dk] for di in (0, 1) for dj in (0, 1) for dk in (0, 1)]
                # corner number b = 4 di + 2 dj + dk
                cells.extend([[c[b] for b in tet] for tet in _KUHN])
    return pts, np.array(cells)


def test_section_is_the_plane_face_with_its_cells():
    pts, tets = _box_tets(4, 2, 3)
    sec = MeridianSection(pts, tets)
    assert np.all(pts[sec.nodes, 1] == 0.0)  # every section node on y = 0
    p2 = sec.points2(pts)
    a, b, c = (p2[sec.triangles[:, i]] for i in range(3))
    area = 0.5 * np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    assert area.sum() == pytest.approx(1.0 * 0.2, rel=1e-12)  # the face y = 0 of the box, exactly
    assert len(sec.triangles) == 2 * 4 * 3  # two triangles per face square
    # each triangle's owner is a tetrahedron that has the triangle as a face
    for tri, cell in zip(sec.nodes[sec.triangles], sec.owner):
        assert set(tri) <= set(tets[cell])
    # r = sqrt(x^2 + y^2): a node moved off the plane keeps its radius
    moved = pts.copy()
    moved[sec.nodes, 1] = 0.3 * moved[sec.nodes, 0]
    assert np.allclose(sec.points2(moved)[:, 0], np.hypot(pts[sec.nodes, 0], 0.3 * pts[sec.nodes, 0]))


def test_a_body_off_the_plane_is_refused_and_a_case_without_a_sector_has_none(tmp_path):
    pts, tets = _box_tets(2, 1, 1)
    with pytest.raises(ValueError, match="plane y = 0"):
        MeridianSection(pts + np.array([0.0, 0.5, 0.0]), tets)
    (tmp_path / "case.toml").write_text("[case]\nname = 'x'\n")
    assert sector_angle(tmp_path) is None
    (tmp_path / "case.toml").write_text("[sector]\nangle_deg = 1.25\n")
    assert sector_angle(tmp_path) == 1.25
