"""MSH 2.2 writer, mesh builders and the metrics helper (no getdp needed)."""
import numpy as np
import pytest

from pulseform.solvers.getdp import EMMesh, Rect, coil_conductor_mesh, em_metrics, slab_mesh, write_msh22
from pulseform.solvers.getdp.solver import EMStepResult

from getdp_testlib import ten_turn_coil


def test_msh22_round_trip_with_meshio(tmp_path):
    meshio = pytest.importorskip("meshio")
    m = coil_conductor_mesh([ten_turn_coil()], [Rect(0.0, 0.0035, 0.06, 0.0045)], r_domain=0.05, r_shell=0.0625,
                            h_fine=2e-3, h_coarse=1e-2)
    path = write_msh22(m, tmp_path / "m.msh")
    assert path.read_text().startswith("$MeshFormat\n2.2 0 8\n")
    back = meshio.read(path)
    np.testing.assert_allclose(back.points[:, :2], m.points, rtol=0, atol=0)
    tri = back.get_cells_type("triangle")
    np.testing.assert_array_equal(tri, m.triangles)
    phys = back.cell_data_dict["gmsh:physical"]["triangle"]
    np.testing.assert_array_equal(phys, m.tri_tags)
    assert set(np.unique(m.tri_tags)) == {1, 2, 101, 201}
    again = EMMesh.from_meshio(back)
    assert again.same_connectivity(m) and np.array_equal(again.points, m.points)
    assert set(np.unique(m.line_tags)) == {11, 12}
    assert np.all(m.areas() > 0)
    # coil region area = 10 turns of 2 mm x 2 mm
    assert m.region_area(101) == pytest.approx(10 * 4e-6, rel=1e-9)
    # axis lines lie on x = 0, outer lines on the r = 62.5 mm circle
    ax = m.points[m.lines[m.line_tags == 11]]
    assert np.abs(ax[..., 0]).max() < 1e-12
    out = m.points[m.lines[m.line_tags == 12]]
    np.testing.assert_allclose(np.hypot(out[..., 0], out[..., 1]), 0.0625, rtol=1e-6)


def test_slab_and_volumes():
    m = slab_mesh(1e-3, 1e-4)
    assert m.n_nodes == 22 and len(m.triangles) == 20
    assert m.volumes(False).sum() == pytest.approx(1e-7)
    ring = EMMesh([[1.0, 0.0], [2.0, 0.0], [1.0, 1.0]], [[0, 1, 2]], [201])
    # exact volume of the revolved triangle: 2 pi * r_centroid * area
    assert ring.volumes(True)[0] == pytest.approx(2 * np.pi * (4 / 3) * 0.5)
    with pytest.raises(ValueError):
        slab_mesh(1e-3, 3e-4)
    with pytest.raises(ValueError):
        m.with_points(m.points[:-1])
    assert EMMesh.from_dict(m.to_dict()).same_connectivity(m)


def _fake_result(dt, current, force, heat, rise):
    n = len(current)
    z = np.zeros
    return EMStepResult(times=dt * np.arange(1, n + 1), dt=dt, elements=z(0, int), element_tags=z(0, int),
                        force_density=z((n, 0, 2)), force_density_centroid=z((n, 0, 2)), joule_density=z((n, 0)),
                        flux_density=z((n, 0, 2)), coil_current=np.asarray(current, float)[:, None],
                        coil_voltage=z((n, 1)), coil_power=z((n, 1)), coil_force=z((n, 1, 2)),
                        conductor_force=np.asarray(force, float)[:, None, :], conductor_power=z((n, 1)),
                        magnetic_energy=z(n), capacitor_voltage=None, circuit_current=None,
                        coil_heat=np.array([heat]), coil_temperature_rise=np.array([rise]), probe_b=z((n, 0, 2)))


def test_em_metrics():
    r1 = _fake_result(1e-6, [1e3, -25e3], [[0, 100.0], [0, 300.0]], 10.0, 0.5)
    r2 = _fake_result(2e-6, [5e3], [[0, -50.0]], 12.0, 0.7)
    m = em_metrics([r1, r2])
    assert m["coil_current_peak_kA"] == pytest.approx(25.0)
    assert m["force_impulse_Ns"] == pytest.approx(400e-6 - 100e-6)
    assert m["coil_joule_heat_J"] == pytest.approx(12.0)
    assert m["coil_temperature_rise_K"] == pytest.approx(0.7)
    with pytest.raises(ValueError):
        em_metrics([])


def test_em_metrics_axisymmetric_impulse_is_axial():
    """Issue 32, item 5: in axisymmetry the (r, z) force sums' r part is a load round the ring with no net force:
    the impulse is the axial one, the radial load's is its own figure (the planar impulse stays |(x, y)|)."""
    r1 = _fake_result(1e-6, [1e3], [[30.0, 40.0]], 1.0, 0.1)
    r2 = _fake_result(1e-6, [1e3], [[30.0, -20.0]], 1.0, 0.1)
    planar = em_metrics([r1, r2])
    assert planar["force_impulse_Ns"] == pytest.approx(np.hypot(60e-6, 20e-6), rel=1e-15)
    assert "radial_load_impulse_Ns" not in planar
    axi = em_metrics([r1, r2], axisymmetric=True)
    assert axi["force_impulse_Ns"] == pytest.approx(20e-6, rel=1e-15)
    assert axi["radial_load_impulse_Ns"] == pytest.approx(60e-6, rel=1e-15)


def test_package_imports_neither_orchestrator_nor_dolfinx():
    import subprocess
    import sys
    code = ("import sys, pulseform.solvers.getdp; "
            "print([m for m in sys.modules if m.startswith(('pulseform.orchestrator', 'pulseform.solvers.dolfinx',"
            " 'dolfinx'))])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_case_deck_defaults_are_the_mesh_ids():
    """The physical ids are defined once (:mod:`pulseform.solvers.getdp.mesh`) and reach the built-in
    deck with -setnumber; the deck's DefineConstant defaults (for a standalone run) repeat them."""
    import re

    from pulseform.solvers.getdp.mesh import coil_tag, conductor_tag, physical_numbers
    from pulseform.solvers.getdp.solver import CASE_DECK

    text = re.sub(r"//[^\n]*", "", CASE_DECK.read_text())
    defaults = {name: float(v) for name, v in re.findall(r"(Phys_\w+)\s*=\s*([0-9.]+)\s*[,\]]", text)}
    assert defaults == physical_numbers()
    assert (coil_tag(3), conductor_tag(2)) == (defaults["Phys_Coil_Base"] + 3, defaults["Phys_Cond_Base"] + 2)
