"""EM geometry builders and the workpiece mesh cut from the EM mesh (no getdp needed)."""

import math

import numpy as np
import pytest

from pulseform.orchestrator.case.model import FlatCoilSheet, SolenoidTube
from pulseform.orchestrator.mesh.em_geometry import build_em_geometry, flat_coil_turns, solenoid_turns
from pulseform.orchestrator.mesh.shared import conductor_submesh, match_nodes, to_dolfinx
from pulseform.orchestrator.coupling.transfer import cell_volumes
from pulseform.solvers.getdp.mesh import AIR, AXIS, OUTER, SHELL

SHEET = FlatCoilSheet(type="flat_coil_sheet", turns=3, coil_inner_radius=10e-3, turn_width=4e-3,
                      turn_height=3e-3, turn_gap=1e-3, coil_gap=1.5e-3, sheet_radius=40e-3,
                      sheet_thickness=1e-3, air_radius=0.1, shell_radius=0.13, mesh_size_sheet=1e-3,
                      mesh_size_coil=2e-3, mesh_size_air=0.02)


@pytest.fixture(scope="module")
def sheet_geometry():
    return build_em_geometry(SHEET)


def test_regions_and_exact_areas(sheet_geometry):
    """Every region is there; the straight-sided regions have their exact areas and volumes."""
    m = sheet_geometry.mesh
    tags = set(np.unique(m.tri_tags))
    assert {AIR, SHELL, sheet_geometry.regions["coil"], sheet_geometry.regions["workpiece"]} <= tags
    assert {AXIS, OUTER} <= set(np.unique(m.line_tags))
    assert m.region_area(sheet_geometry.regions["coil"]) == pytest.approx(3 * 4e-3 * 3e-3, rel=1e-12)
    assert m.region_area(sheet_geometry.regions["workpiece"]) == pytest.approx(40e-3 * 1e-3, rel=1e-12)
    sub = conductor_submesh(m, sheet_geometry.regions["workpiece"])
    v = cell_volumes(sub.points, sub.cells, axisymmetric=True).sum()
    assert v == pytest.approx(math.pi * 40e-3 ** 2 * 1e-3, rel=1e-12)  # disk π R² t


def test_turn_layout():
    turns = flat_coil_turns(SHEET)
    assert [round(t.x0 * 1e3, 9) for t in turns] == [10.0, 15.0, 20.0]
    assert all(t.y1 == 0.0 and t.y0 == -3e-3 for t in turns)
    tube = SolenoidTube(type="solenoid_tube", turns=4, coil_inner_radius=12e-3, turn_width=3e-3,
                        turn_height=3e-3, turn_gap=1e-3, tube_inner_radius=17e-3, tube_thickness=1.5e-3,
                        tube_length=40e-3, air_radius=0.1, shell_radius=0.13, mesh_size_tube=1e-3,
                        mesh_size_coil=2e-3, mesh_size_air=0.02)
    st = solenoid_turns(tube)
    assert st[0].y0 == pytest.approx(-st[-1].y1) and st[1].y0 - st[0].y0 == pytest.approx(4e-3)


def test_mechanical_mesh_shares_the_em_nodes(sheet_geometry):
    """The DOLFINx mesh of the workpiece has exactly the EM workpiece nodes (same coordinates)."""
    m = sheet_geometry.mesh
    sub = conductor_submesh(m, sheet_geometry.regions["workpiece"])
    dm = to_dolfinx(sub)
    x = dm.geometry.x[:, :2]
    assert len(x) == len(sub.em_nodes)
    idx = match_nodes(x, m.points, tol=0.0)
    assert set(idx) == set(sub.em_nodes)
    assert dm.topology.index_map(2).size_local == len(sub.rows)
    with pytest.raises(ValueError, match="do not share nodes"):
        match_nodes(x + 1e-6, m.points, tol=1e-9)


def test_coaxial_coils_regions_and_a_remesh_keep_every_coil():
    """coaxial_coils: coil k is physical 100 + k with exactly its windings' area, the workpiece 201 its
    rectangle; a remesh around the (moved) workpiece meshes every coil again with the same areas."""
    from pulseform.orchestrator.case.em_model import CoaxialCoils
    from pulseform.orchestrator.case.schema import from_dict
    from pulseform.orchestrator.mesh.remesh import remesh_around

    g = from_dict(CoaxialCoils, {
        "type": "coaxial_coils", "air_radius": 0.1, "shell_radius": 0.13, "mesh_size_coil": 2e-3,
        "mesh_size_air": 0.02, "workpiece": {"r0": 5e-3, "z0": 1e-3, "r1": 40e-3, "z1": 2e-3, "mesh_size": 1e-3},
        "coils": [{"name": "a", "turns": 3, "windings": [[8e-3, -3e-3, 14e-3, 0.0]]},
                  {"name": "b", "turns": 2, "windings": [[20e-3, -3e-3, 24e-3, 0.0], [26e-3, -2e-3, 30e-3, 0.0]]}]},
        "geometry")
    geo = build_em_geometry(g)
    m = geo.mesh
    areas = {101: 6e-3 * 3e-3, 102: 4e-3 * 3e-3 + 4e-3 * 2e-3, 201: 35e-3 * 1e-3}
    assert [t for t, _ in geo.coil_turns()] == [101, 102] and geo.conductor_roles() == ["workpiece"]
    assert m.names[101] == "a" and m.names[102] == "b" and m.names[201] == "workpiece"
    for tag, area in areas.items():
        assert m.region_area(tag) == pytest.approx(area, rel=1e-12), tag
    sub = conductor_submesh(m, 201)
    moved = sub.points + np.array([0.0, 0.3e-3])  # the ring lifted by 0.3 mm
    new, (index,) = remesh_around([(moved, sub.cells, 201)], geo.coil_turns(), 0.1, 0.13, 2e-3, 0.02)
    for tag, area in areas.items():
        assert new.region_area(tag) == pytest.approx(area, rel=1e-12), tag
    assert np.array_equal(new.points[index], moved)
