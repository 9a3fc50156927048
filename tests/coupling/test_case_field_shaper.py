"""The slotted field-shaper tube-compression case (cases/emf_tube_field_shaper, issue 29 deliverable 5): a
3D case from a hand-written Gmsh .geo (OpenCASCADE, DefineConstant parameters, BooleanFragments, named groups).

Default tier (a few seconds): the case's geometry file meshed coarse through the case's own role map
(build_geometry3d, em_model3d), then two BDF2 steps (2 us) of the fixed-mesh 3D EM solve with the case's
bank. Physics checked (the field-shaper principle: a transformer whose secondary is the shaper):
* the shaper's induced current runs against the coil's on its outer face and, having crossed the slit's
  faces, with the coil's on its inner face, where it is concentrated (the inner face is 15 mm long
  against the 40 mm outer face: higher Joule density there);
* the tube's current runs against the coil's; its resultant radial force points inwards and its force along
  the slit's axis (x) is small beside it (the slit breaks the rotational symmetry only there); the coil is
  pushed outwards;
* the slit: near its face the shaper's current is radial (it turns from the outer to the inner face).
The current direction comes from GetDP's per-element f = j x B and B (both printed per element): the
component of j normal to B is B x f / |B|^2; here j is azimuthal and B meridional, so it is all of j.

A .geo with inconsistent dimensions fails with its own message (one line); a [[symmetry]] plane the model
does not end on is refused (one line).

Slow tier: the mid-plane's "b_normal" condition against the same device modelled over both halves in z.

Slow tier: the case run end to end by the CLI at coarse sizes: the tube is compressed (its mid-section
moves inwards, plastically), the EM mesh follows, the ledgers hold.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from pulseform.orchestrator.case.io import load_case
from pulseform.orchestrator.em.model3d import em_model3d
from pulseform.orchestrator.mesh.geometry3d import build_geometry3d
from pulseform.solvers.getdp.mesh import conductor_tag
from pulseform.solvers.getdp.solver3d import solve_transient3d
from warm_cli import pulseform_cli

REPO = Path(__file__).resolve().parents[2]
CASE = str(REPO / "cases/emf_tube_field_shaper")
#: a coarse mesh of the case (~14k EM tets, ~1 s per EM step)
COARSE = {"geometry.mesh_sizes.tube": 3e-3, "geometry.mesh_sizes.shaper": 4e-3, "geometry.mesh_sizes.coil": 8e-3,
          "geometry.parameters.mesh_size_air": 0.03, "geometry.parameters.mesh_size_shell": 0.04}


@pytest.fixture(scope="module")
def em_first_steps(tmp_path_factory):
    work = tmp_path_factory.mktemp("field_shaper_em")
    case, _ = load_case(CASE, [f"{k}={v!r}" for k, v in COARSE.items()])
    geo = build_geometry3d(case, work)
    model = em_model3d(case, geo)
    res = solve_transient3d(model, geo.mesh, t_end=2e-6, n_steps=2, work_dir=work / "getdp", element_output="last",
                            time_scheme="bdf2")
    return case, geo, model, res


def _fields(geo, res, k):
    """(centroids m, volumes m^3, force density N/m^3, B T, Joule density W/m^3, j normal to B A/m^2) of
    conductor k's elements after the last step."""
    sel = res.element_tags == conductor_tag(k)
    rows = res.elements[sel]
    f, b = res.force_density[-1][sel], res.flux_density[-1][sel]
    j = np.cross(b, f) / np.einsum("ij,ij->i", b, b)[:, None]
    return geo.mesh.centroids(rows), geo.mesh.volumes(rows), f, b, res.joule_density[-1][sel], j


def _cyl(c):
    r = np.hypot(c[:, 0], c[:, 1])
    e_r = np.c_[c[:, 0] / r, c[:, 1] / r, np.zeros(len(r))]
    e_phi = np.c_[-c[:, 1] / r, c[:, 0] / r, np.zeros(len(r))]
    return r, e_r, e_phi


@pytest.mark.getdp
def test_geometry_file_roles(em_first_steps):
    case, geo, model, res = em_first_steps
    assert geo.conductors == {"tube": 1, "shaper": 2} and geo.coils == {"coil": 1}
    assert model.symmetry_factor == 4.0 and geo.shell[1] == pytest.approx(0.15, rel=1e-6)
    assert 0.97 * 0.12 < geo.shell[0] <= 0.12   # R_int: the nearest plane of the faceted inner sphere's faces
    p = case.geometry.parameters
    # the coil's section from the mesh (V / (r alpha), alpha = 360 / 4 deg) is its whole meridian section
    from pulseform.solvers.getdp.solver3d import coil_section_from_mesh
    assert coil_section_from_mesh(geo.mesh, 1) == pytest.approx(p["t_coil"] * p["L_coil"], rel=0.02)
    # the symmetry planes of the role map: y = 0 n x a = 0 (14), z = 0 natural (15)
    assert [pl.field for pl in geo.planes] == ["b_tangential", "b_normal"]


@pytest.mark.getdp
def test_shaper_currents_and_tube_force(em_first_steps):
    case, geo, model, res = em_first_steps
    p = case.geometry.parameters
    current = res.coil_current[-1, 0]
    assert current > 1e3   # the bank's first half-wave: positive along +e_phi
    s = np.sign(current)
    r_bore = p["R_tube_in"] + p["t_tube"] + p["gap_tube"]

    # the shaper: outer face against the coil, inner face with it, concentrated on the inner face
    c, v, f, b, q, j = _fields(geo, res, 2)
    r, e_r, e_phi = _cyl(c)
    j_phi = np.einsum("ij,ij->i", j, e_phi)
    j_r = np.einsum("ij,ij->i", j, e_r)
    away = np.abs(np.arctan2(c[:, 1], c[:, 0])) > np.radians(30)   # away from the slit (at phi = 0)
    outer = away & (r > p["R_shaper"] - 4e-3)
    inner = away & (r < r_bore + 4e-3) & (c[:, 2] < p["L_inner"] / 2)
    assert outer.sum() > 20 and inner.sum() > 5
    outer_phi = s * np.sum(j_phi[outer] * v[outer]) / v[outer].sum()
    inner_phi = s * np.sum(j_phi[inner] * v[inner]) / v[inner].sum()
    assert outer_phi < 0 < inner_phi, (outer_phi, inner_phi)
    q_outer, q_inner = np.average(q[outer], weights=v[outer]), np.average(q[inner], weights=v[inner])
    assert q_inner > 2.0 * q_outer, (q_inner, q_outer)
    # the slit's face (y = w/2, x > 0): the current turns radially there, from the outer face to the inner
    near_slit = (c[:, 0] > 0) & (c[:, 1] < p["w_slit"] / 2 + 3e-3) & (c[:, 2] < p["L_inner"] / 2)
    assert near_slit.sum() > 5
    assert np.sum(np.abs(j_r[near_slit]) * v[near_slit]) > np.sum(np.abs(j_phi[near_slit]) * v[near_slit])
    assert s * np.sum(j_r[near_slit] * v[near_slit]) < 0   # inwards: the outer face's current (-e_phi) turning in

    # the tube: its current against the coil's, its resultant radial force inwards, little force along x
    c, v, f, b, q, j = _fields(geo, res, 1)
    r, e_r, e_phi = _cyl(c)
    assert s * np.sum(np.einsum("ij,ij->i", j, e_phi) * v) < 0
    f_r = np.sum(np.einsum("ij,ij->i", f, e_r) * v)   # N, the quarter's resultant radial force
    assert f_r < 0
    total = (f * v[:, None]).sum(0)
    assert total[1] < 0 and abs(total[1]) > 0.5 * abs(f_r)   # the half-tube y > 0 is pushed towards -y
    assert abs(total[0]) < 0.1 * abs(f_r), (total, f_r)       # along the slit's axis: the slit's small imbalance
    assert abs(total[2]) < 0.2 * abs(f_r), (total, f_r)       # axial: the concentrated zone's ends only
    # GetDP's own integral over the region equals the per-element sum
    assert res.conductor_force[-1, 0] == pytest.approx(total, rel=1e-6, abs=1e-9 * abs(f_r))
    # the coil is pushed outwards (the quarter coil towards +y)
    assert res.coil_force[-1, 0, 1] > 0


def test_inconsistent_dimensions_name_the_geo_error(tmp_path):
    """The .geo's own Error(...) (here a taper radius outside the shaper) reaches the user as its message (the
    meshing child used to report the line of gmsh's Python traceback that contains 'rror')."""
    from pulseform.orchestrator.mesh.geometry3d import GeometryError

    case, _ = load_case(CASE, ["geometry.parameters.R_taper=0.05"])
    with pytest.raises(GeometryError, match=r"gmsh failed: Error: field_shaper.geo: inconsistent dimensions"):
        build_geometry3d(case, tmp_path)


@pytest.mark.slow
@pytest.mark.getdp
def test_mid_plane_symmetry_b_normal(tmp_path):
    """The z = 0 plane's condition (field = "b_normal": n x h = 0, natural) against the model without it: the
    .geo's z_symmetric = 0 builds both halves in z (the half y >= 0, one [[symmetry]] plane, factor 2). Design
    mesh, two BDF2 steps: the coil current and the magnetic energy within 1 %, the coil's and the tube's
    radial (y) forces = 2 x the quarter's within 2 % and 4 % (measured 0.6 %, 0.3 %, 1.3 %, 1.8 %: the two
    meshes differ; on the coarse mesh the tube's force differed by 11 %, the rest by <= 0.3 %), and the
    whole-z model's axial forces ~0. A wrong mid-plane condition (n x a = 0 would force B along the plane,
    where the solenoid's field crosses it) changes the inductance and these figures grossly."""
    import dataclasses

    runs = {}
    for z_symmetric in (1, 0):
        case, _ = load_case(CASE, [f"geometry.parameters.z_symmetric={z_symmetric}"])
        if not z_symmetric:
            case = dataclasses.replace(case, symmetry=tuple(s for s in case.symmetry if s.field == "b_tangential"))
        geo = build_geometry3d(case, tmp_path / f"z{z_symmetric}")
        model = em_model3d(case, geo)
        assert model.symmetry_factor == (4.0 if z_symmetric else 2.0)
        runs[z_symmetric] = solve_transient3d(model, geo.mesh, t_end=2e-6, n_steps=2, element_output="none",
                                              work_dir=tmp_path / f"z{z_symmetric}" / "getdp", time_scheme="bdf2")
    q, h = runs[1], runs[0]
    assert h.coil_current[-1, 0] == pytest.approx(q.coil_current[-1, 0], rel=0.01)
    assert h.magnetic_energy[-1] == pytest.approx(2 * q.magnetic_energy[-1], rel=0.01)
    assert h.coil_force[-1, 0, 1] == pytest.approx(2 * q.coil_force[-1, 0, 1], rel=0.02)
    assert h.conductor_force[-1, 0, 1] == pytest.approx(2 * q.conductor_force[-1, 0, 1], rel=0.04)
    assert abs(h.conductor_force[-1, 0, 2]) < 0.02 * abs(h.conductor_force[-1, 0, 1])
    assert abs(h.coil_force[-1, 0, 2]) < 0.02 * abs(q.coil_force[-1, 0, 2])   # the halves' axial pulls cancel


def test_symmetry_plane_the_model_does_not_end_on(tmp_path):
    """Both halves in z (z_symmetric = 0) but the case's z = 0 [[symmetry]] entry kept: the plane holds no
    boundary face, and the run stops with one line naming it (it used to go on silently with a symmetry factor
    of 4 for a half model: the bank's voltage over the part halved, the device figures scaled by 4, not 2)."""
    from pulseform.orchestrator.mesh.geometry3d import GeometryError

    sizes = [f"{k}={v!r}" for k, v in COARSE.items()] + ["geometry.mesh_sizes.tube=6e-3", "geometry.mesh_sizes.shaper=8e-3"]
    case, _ = load_case(CASE, sizes + ["geometry.parameters.z_symmetric=0"])
    with pytest.raises(GeometryError, match=r"symmetry\[1\]: the plane .* holds no boundary face"):
        build_geometry3d(case, tmp_path)


def _history(out: Path) -> dict[str, np.ndarray]:
    rows = list(csv.DictReader(open(out / "history.csv")))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


@pytest.mark.slow
@pytest.mark.getdp
def test_coupled_run_compresses_the_tube(tmp_path):
    out = tmp_path / "run"
    sets = [a for k, v in COARSE.items() for a in ("--set", f"{k}={v!r}")]
    r = pulseform_cli(["run", CASE, "--out", str(out), "--quiet", "--set", "time.end=20e-6",
                       "--set", "output.field_interval=10e-6", *sets])
    assert r.returncode == 0, r.stderr[-3000:]
    m = json.loads((out / "metrics.json").read_text())
    h = _history(out)
    assert m["status_ok"] == 1 and m["conservation_error_rel"] < 1e-10
    assert m["tube_max_ux_mm"] > 0.1 and m["plastic_work_J"] > 0.0
    assert np.all(h["force_y_N"][1:] <= 0.0)   # the half-tube pushed towards the axis (y < 0) throughout
    assert m["energy_error_rel"] < 0.02
