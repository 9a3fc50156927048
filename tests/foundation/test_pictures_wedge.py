"""A wedge model unfolded by its symmetry for the mechanics pictures (orchestrator/run/pictures_wedge.py): a 3D
model between two [[symmetry]] planes through the z-axis, drawn over 270 degrees about z.

References (exact by construction, to round-off): the copies are isometries that keep each node's distance from
the z-axis and its z; copy k covers the angles [k a, (k + 1) a]; the faces on the planes are drawn only at the two
open cuts, and the faces off them once per copy; each face belongs to the tetrahedron that colours it."""

import math

import numpy as np
import pytest

from pulseform.orchestrator.run.pictures_wedge import UNFOLD_DEG, UnfoldedBody, Wedge, wedge_planes

#: the six tetrahedra of a unit cube (Kuhn split: all around the diagonal from corner 0 to corner 7)
_KUHN = np.array([[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]])


def _wedge_tets(alpha: float, nr: int = 4, nt: int = 2, nz: int = 3, r=(1.0, 2.0), h=0.2):
    """A structured tetrahedral mesh of r in ``r``, 0 <= phi <= ``alpha`` (rad), 0 <= z <= h (Kuhn cubes mapped to
    cylindrical coordinates)."""
    g = [np.linspace(r[0], r[1], nr + 1), np.linspace(0.0, alpha, nt + 1), np.linspace(0.0, h, nz + 1)]
    R, P, Z = np.meshgrid(*g, indexing="ij")
    pts = np.column_stack([(R * np.cos(P)).ravel(), (R * np.sin(P)).ravel(), Z.ravel()])
    idx = np.arange(len(pts)).reshape(nr + 1, nt + 1, nz + 1)
    cells = []
    for i in range(nr):
        for j in range(nt):
            for k in range(nz):
                c = [idx[i + di, j + dj, k + dk] for di in (0, 1) for dj in (0, 1) for dk in (0, 1)]
                cells.extend([[c[b] for b in tet] for tet in _KUHN])
    return pts, np.array(cells)


def _area(p, f):
    return 0.5 * float(np.linalg.norm(np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]]), axis=1).sum())


@pytest.mark.parametrize("deg", [5.0, 40.0])
def test_the_wedge_unfolds_by_its_symmetry(deg):
    alpha = math.radians(deg)
    pts, tets = _wedge_tets(alpha)
    normals = [np.array([0.0, 1.0, 0.0]), np.array([math.sin(alpha), -math.cos(alpha), 0.0])]  # any sign
    w = Wedge.of(normals, pts)
    assert w.angle == pytest.approx(alpha, rel=1e-12) and np.allclose(w.e1, [1.0, 0.0, 0.0], atol=1e-15)
    body = UnfoldedBody(w, pts, tets)
    off, first, second = body.faces
    # the faces on each plane: the section r in [1, 2], z in [0, 0.2] of the wedge, exactly
    assert np.all(pts[first, 1] == 0.0)
    assert np.abs(pts[second] @ normals[1]).max() < 1e-15
    assert _area(pts, first) == pytest.approx(0.2, rel=1e-12) and _area(pts, second) == pytest.approx(0.2, rel=1e-12)
    for faces, owner in zip(body.faces, body.owner):   # each face is a face of the cell that colours it
        assert all(set(f) <= set(tets[c]) for f, c in zip(faces, owner))
    values = np.arange(len(tets), dtype=float)
    x, flat, v = body.surface(pts, values)
    m = w.copies
    assert m == math.ceil(UNFOLD_DEG / deg - 1e-9) and len(x) == m * len(pts)
    faces = flat.reshape(-1, 4)
    assert np.all(faces[:, 0] == 3)
    # the off-plane faces once per copy, the plane faces only at the two open cuts; their cells' values
    assert len(faces) == m * len(off) + len(first) + (len(first) if m % 2 == 0 else len(second))
    assert np.array_equal(v[: len(off)], values[body.owner[0]])
    r0 = np.hypot(pts[:, 0], pts[:, 1])
    phi0 = np.arctan2(pts[:, 1], pts[:, 0])
    for k in range(m):
        xk = x[k * len(pts):(k + 1) * len(pts)]
        # an isometry about the z-axis: each node keeps its radius and z
        assert np.allclose(np.hypot(xk[:, 0], xk[:, 1]), r0, rtol=1e-14) and np.array_equal(xk[:, 2], pts[:, 2])
        phi = np.mod(np.arctan2(xk[:, 1], xk[:, 0]) + 1e-12, 2 * np.pi) - 1e-12
        assert phi.min() == pytest.approx(k * alpha, abs=1e-12) and phi.max() == pytest.approx((k + 1) * alpha, abs=1e-12)
        # even copies turn, odd copies mirror: a node at angle phi goes to k a + phi or (k + 1) a - phi
        want = k * alpha + phi0 if k % 2 == 0 else (k + 1) * alpha - phi0
        assert np.allclose(phi, want, atol=1e-12)
    # the unfolded surface's area: the off-plane area m times, plus the two cuts
    total = _area(x, faces[:, 1:])
    assert total == pytest.approx(m * _area(pts, off) + 0.4, rel=1e-12)


def test_wedge_planes_of_a_results_folder(tmp_path):
    f = tmp_path / "case.toml"
    f.write_text("[case]\nname = 'x'\n")
    assert wedge_planes(tmp_path) is None   # no symmetry planes
    three_d = "[mechanics]\nformulation = '3d'\n"
    f.write_text(three_d + "[[symmetry]]\nnormal = [0.0, 1.0, 0.0]\n")
    assert wedge_planes(tmp_path) is None   # one plane
    f.write_text(three_d + "[[symmetry]]\nnormal = [0.0, 1.0, 0.0]\n[[symmetry]]\nnormal = [0.0, 0.0, 1.0]\n")
    assert wedge_planes(tmp_path) is None   # z = 0 does not contain the z-axis
    f.write_text(three_d + "[[symmetry]]\nnormal = [0.0, 1.0, 0.0]\n[[symmetry]]\nnormal = [1.0, 0.0, 0.0]\n"
                 "point = [0.1, 0.0, 0.0]\n")
    assert wedge_planes(tmp_path) is None   # x = 0.1 does not either
    f.write_text(three_d + "[[symmetry]]\nnormal = [0.0, 2.0, 0.0]\n[[symmetry]]\n"
                 "normal = [-0.02181488503456112, 0.9997620270799091, 0.0]\n")
    n = wedge_planes(tmp_path)
    assert n is not None and np.allclose(n[0], [0.0, 1.0, 0.0]) and np.isclose(np.linalg.norm(n[1]), 1.0)
    pts, _ = _wedge_tets(math.radians(1.25))
    assert Wedge.of(n, pts).angle == pytest.approx(math.radians(1.25), rel=1e-12)
    with pytest.raises(ValueError, match="z-axis"):   # bodies around the axis: no wedge to unfold
        Wedge.of(n, np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]))
