"""The racetrack / sheet / grooved-die mesh (issue 20, case b): regions, volumes, conformity, shared nodes.

References: the volumes are the closed-form volumes of the geometry's boxes (sheet, die minus
groove) and of the turns (straight bars + quarter annuli: faceting of the arcs leaves them a little
below, bounded by the chord error); the electrode area is the turns' cross-sections (exact).
"""
import math

import numpy as np
import pytest

from pulseform.solvers.getdp.mesh import AIR, OUTER, coil_tag, conductor_tag
from pulseform.solvers.getdp.mesh3d import SYM_A
from pulseform.orchestrator.mesh.shared3d import conductor_submesh3d
from pulseform.solvers.getdp.racetrack_mesh import DIE, SHEET, RacetrackGroove, racetrack_groove_mesh

G = RacetrackGroove()


@pytest.fixture(scope="module")
def quarter(tmp_path_factory):
    return racetrack_groove_mesh(tmp_path_factory.mktemp("rt") / "quarter.msh", G)


def region_volume(mesh, tag):
    return float(mesh.volumes(np.flatnonzero(mesh.tet_tags == tag)).sum())


def test_regions_and_volumes(quarter):
    m = quarter
    assert m.sector_deg == 90.0
    assert set(np.unique(m.tet_tags)) == {AIR, 2, coil_tag(1), conductor_tag(SHEET), conductor_tag(DIE)}
    # sheet: a box (exact up to round-off)
    assert region_volume(m, conductor_tag(SHEET)) == pytest.approx(G.sheet_half_x * G.sheet_half_y * G.sheet_thickness,
                                                                   rel=1e-9)
    gx0, gx1 = G.groove_x
    die = G.die_half_x * G.die_half_y * G.die_height - (gx1 - gx0) * G.groove_half_length * G.groove_depth
    assert region_volume(m, conductor_tag(DIE)) == pytest.approx(die, rel=1e-9)
    h = G.turn_height
    coil = sum((x1 - x0) * h * G.half_straight + math.pi / 4 * (x1 ** 2 - x0 ** 2) * h
               for x0, x1 in map(G.turn_x, range(G.turns)))
    v = region_volume(m, coil_tag(1))
    assert v < coil and v == pytest.approx(coil, rel=5e-3)
    # electrode: the turns' sections on y = 0
    assert m.electrode_area[1] == pytest.approx(G.turns * G.turn_width * G.turn_height, rel=1e-12)
    # the sheet is layered: its nodes lie on sheet_layers + 1 planes
    sheet = conductor_submesh3d(m, conductor_tag(SHEET))
    z = np.unique(np.round(sheet.points[:, 2] / G.sheet_thickness * G.sheet_layers, 9))
    np.testing.assert_array_equal(z, np.arange(G.sheet_layers + 1))


def test_boundaries_are_the_planes_and_the_sphere(quarter):
    text = quarter.path.read_text()
    body = text.split("$Elements\n", 1)[1].split("$EndElements", 1)[0].splitlines()[1:]
    tri = {}
    for r in body:
        v = r.split()
        if v[1] == "2":
            tri.setdefault(int(v[3]), []).append([int(i) for i in v[-3:]])
    ids = np.array(text.split("$Nodes\n", 1)[1].split("$EndNodes")[0].split()[1:], float).reshape(-1, 4)
    xyz = dict(zip(ids[:, 0].astype(int), ids[:, 1:]))
    sym = np.array([[xyz[i] for i in t] for t in tri[SYM_A]])
    on_plane = np.all(np.abs(sym[..., 0]) < 1e-12, axis=1) | np.all(np.abs(sym[..., 1]) < 1e-12, axis=1)
    assert on_plane.all()
    outer = np.array([[xyz[i] for i in t] for t in tri[OUTER]])
    np.testing.assert_allclose(np.linalg.norm(outer, axis=2), G.shell_radius, rtol=1e-9)


def test_conductor_meshes_share_the_em_nodes_and_are_conforming(quarter):
    m = quarter
    faces_all = m.tets[:, [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]]].reshape(-1, 3)
    key_all, counts = np.unique(np.sort(faces_all, axis=1), axis=0, return_counts=True)
    assert counts.max() == 2                       # a face is shared by at most two tetrahedra
    interior = {tuple(k) for k in key_all[counts == 2]}
    for k in (SHEET, DIE):
        sub = conductor_submesh3d(m, conductor_tag(k))
        np.testing.assert_array_equal(sub.points, m.points[sub.em_nodes])
        np.testing.assert_array_equal(np.sort(sub.em_nodes[sub.cells], axis=1), np.sort(m.tets[sub.rows], axis=1))
        x = sub.points[sub.cells]
        det = np.einsum("ij,ij->i", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0])
        assert det.min() > 0
        # every skin face off the symmetry planes is a face of an EM tetrahedron outside: conforming
        skin = sub.em_nodes[sub.skin_faces()]
        p = m.points[skin]
        off = ~(np.all(np.abs(p[..., 0]) < 1e-12, axis=1) | np.all(np.abs(p[..., 1]) < 1e-12, axis=1))
        assert off.sum() > 0
        assert all(tuple(f) in interior for f in np.sort(skin[off], axis=1))


def test_half_model_mirrors_the_quarter(tmp_path):
    g = RacetrackGroove(h_sheet=5e-3, sheet_layers=2, h_coil=5e-3, h_die=8e-3, h_air=0.05)
    half = racetrack_groove_mesh(tmp_path / "half.msh", g, half=True)
    assert half.sector_deg == 180.0
    assert region_volume(half, conductor_tag(SHEET)) == pytest.approx(2 * g.sheet_half_x * g.sheet_half_y
                                                                      * g.sheet_thickness, rel=1e-9)
    assert half.electrode_area[1] == pytest.approx(g.turns * g.turn_width * g.turn_height, rel=1e-12)
    c = half.centroids(np.flatnonzero(half.tet_tags == coil_tag(1)))
    assert c[:, 0].min() < -g.bend_radius and c[:, 0].max() > g.bend_radius and c[:, 1].min() > 0


def test_bad_geometry_is_refused():
    with pytest.raises(ValueError, match="groove_half_length"):
        RacetrackGroove(groove_half_length=0.1).validate()
    with pytest.raises(ValueError, match="sheet_half_x"):
        RacetrackGroove(sheet_half_x=0.01).validate()
    with pytest.raises(ValueError, match="turns"):
        RacetrackGroove(turns=0).validate()
