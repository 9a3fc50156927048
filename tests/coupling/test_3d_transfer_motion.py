"""3D coupling pieces without getdp: shared conductor meshes, consistent nodal forces and their ledger,
harmonic air motion with sliding symmetry planes.

References: the ledger is exact by construction (Σ_i f V_e / 4 over the four nodes = f V_e), checked
against the element volumes computed independently (numpy determinants) and against the analytic
volume of the sector ring; the mesh motion reproduces fields that are harmonic and tangent to the
planes exactly (a rigid translation along the axis, a uniform radial expansion ε (x, y, 0): linear,
hence harmonic, and tangent to both meridian planes of a sector), so any error there is the solver's.
"""
import math

import numpy as np
import pytest

from pulseform.orchestrator.coupling.transfer import ledger_error
from pulseform.orchestrator.coupling.transfer3d import tet_force_integral, tet_nodal_forces
from pulseform.orchestrator.mesh.motion import MeshQualityError
from pulseform.orchestrator.mesh.motion3d import MeshMover3D, nodes_on_plane, tet_quality
from pulseform.orchestrator.mesh.shared3d import conductor_submesh3d, match_nodes3d, to_dolfinx3d
from pulseform.solvers.getdp import Rect
from pulseform.solvers.getdp.mesh import OUTER, conductor_tag
from pulseform.solvers.getdp.mesh3d import ring_sector_mesh

SECTOR = 5.0


@pytest.fixture(scope="module")
def sector_mesh(tmp_path_factory):
    path = tmp_path_factory.mktemp("m3d") / "sector.msh"
    turns = [Rect(0.012 + i * 0.006, -0.004, 0.016 + i * 0.006, -0.001) for i in range(3)]
    return ring_sector_mesh(path, turns, [Rect(0.0, 0.0, 0.05, 0.001)], sector_deg=SECTOR, h_coil=3e-3,
                            h_conductor=2e-3, h_air=0.02, conductor_layers=2)


def _outer_nodes(mesh):
    """Nodes on the outer sphere (the far boundary: fixed in the coupled runs)."""
    r = np.linalg.norm(mesh.points, axis=1)
    return np.flatnonzero(r >= r.max() * (1 - 1e-9))


def _planes(mesh):
    a = math.radians(SECTOR)
    tol = 1e-9
    return [(nodes_on_plane(mesh.points, (0, 0, 0), (0, 1, 0), tol), np.array([0.0, 1.0, 0.0])),
            (nodes_on_plane(mesh.points, (0, 0, 0), (-math.sin(a), math.cos(a), 0), tol),
             np.array([-math.sin(a), math.cos(a), 0.0]))]


def test_shared_nodes_and_ledger_at_round_off(sector_mesh):
    sub = conductor_submesh3d(sector_mesh, conductor_tag(1))
    dmsh = to_dolfinx3d(sub)
    x_body = dmsh.geometry.x
    body_to_em = match_nodes3d(x_body, sector_mesh.points, 1e-12)
    assert len(np.unique(body_to_em)) == len(x_body) == len(sub.em_nodes)
    rng = np.random.default_rng(1)
    f = rng.normal(size=(len(sub.cells), 3)) * 1e9 + np.array([0.0, 0.0, 5e9])   # N/m^3
    nodal = tet_nodal_forces(sub.points, sub.cells, f)
    integral = tet_force_integral(sub.points, sub.cells, f)
    p = sub.points[sub.cells]
    vol = np.abs(np.linalg.det(np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]], 1))) / 6
    err = ledger_error(nodal, integral)
    err_ind = np.abs(nodal.sum(0) - (f * vol[:, None]).sum(0)).max() / np.abs(integral).max()
    # the disk sector of radius 50 mm, 1 mm thick (faceted arc: volume a little below the analytic one)
    v_exact = 0.5 * math.radians(SECTOR) * 0.05 ** 2 * 1e-3
    print(f"\nledger {err:.1e}, vs independent volumes {err_ind:.1e}; conductor volume {vol.sum() / v_exact - 1:+.2e} "
          "from the analytic sector")
    assert err < 1e-13 and err_ind < 1e-13
    assert abs(vol.sum() / v_exact - 1) < 5e-3


def test_mesh_motion_reproduces_harmonic_fields_tangent_to_the_planes(sector_mesh):
    m = sector_mesh
    cond = np.unique(m.tets[m.tet_tags == conductor_tag(1)])
    prescribed = np.union1d(cond, _outer_nodes(m))
    mover = MeshMover3D(m.points, m.tets, prescribed, _planes(m))
    for name, field in (("translation along z", lambda x: np.tile([0.0, 0.0, 2e-4], (len(x), 1))),
                        ("radial expansion", lambda x: 1e-3 * np.c_[x[:, 0], x[:, 1], np.zeros(len(x))])):
        u = mover.displace(field(m.points))
        err = np.abs(u - field(m.points)).max() / np.abs(field(m.points)).max()
        print(f"\n{name}: max error {err:.1e} of the field's scale")
        assert err < 1e-10


def test_mesh_motion_keeps_plane_nodes_on_their_planes_and_watches_quality(sector_mesh):
    m = sector_mesh
    cond = np.unique(m.tets[m.tet_tags == conductor_tag(1)])
    prescribed = np.union1d(cond, _outer_nodes(m))
    planes = _planes(m)
    mover = MeshMover3D(m.points, m.tets, prescribed, planes, min_quality=0.3 * tet_quality(m.points, m.tets).min())
    # the conductor bulges: u_z = 2 mm (1 - (r/R)^2), zero at the rim, tangent to both planes
    r = np.hypot(m.points[:, 0], m.points[:, 1])
    ug = np.zeros_like(m.points)
    ug[:, 2] = 2e-3 * np.clip(1 - (r / 0.05) ** 2, 0, None)
    x = mover.moved(ug)
    for nodes, n in planes:
        free = np.setdiff1d(nodes, prescribed)
        assert len(free) > 10
        assert np.abs(x[free] @ n).max() < 1e-15
    axis = np.intersect1d(planes[0][0], planes[1][0])
    assert np.abs(x[np.setdiff1d(axis, prescribed), :2]).max() < 1e-15   # the axis nodes slide along z only
    assert mover.last_min_quality > 0
    ug[cond, 2] = 0.02 * np.clip(1 - (r[cond] / 0.05) ** 2, 0, None)   # 20 mm: through the coil
    with pytest.raises(MeshQualityError, match="remesh"):
        mover.moved(ug)
