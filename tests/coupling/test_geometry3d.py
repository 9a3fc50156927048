"""A coupled 3D case from a geometry file written by hand, the way a user writes one (issue 29):
``tests/coupling/data/two_coils_plate.geo`` -- two half-ring coils on their own sources under an aluminium plate
held at its ends (a deformable body on a surface group), a copper slug above it (a rigid body), air and a
shell, half model y >= 0 -- meshed by the runner, its named groups mapped by the case's role map, run through
``pulseform run`` with coupling.n = 3; and every bad input of the role map: one line, exit 2.

References: (1) the terminals' area is the coil's section (turns' cross-section (r1 - r0) hc, exact for plane
faces); (2) the coils carry their sources' prescribed currents (GetDP's tables, 10 digits); (3) the force
ledgers (Σ nodal forces vs Σ f V) are exact by construction: round-off; (4) the plate's held nodes do not move;
(5) Newton on the rigid slug: m v = the impulse of its held Lorentz forces (central differences with a held
force are exact; the first step is a half step); (6) the energy ledger of the explicit solver.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import meshio
import numpy as np
import pytest

from pulseform.orchestrator.cli import main

from .bad_input import one_line_refusal

DATA = Path(__file__).resolve().parent / "data"
GEO = "two_coils_plate.geo"
#: sources of the test case (A, Hz, rad): coil a on sa, coil b on sb wound the other way
SA, SB = (5e3, 20e3, 0.0), (8e3, 30e3, 0.5)

CASE = f'''
[case]
name = "two_coils_plate_3d"
kind = "coupled"

[time]
end = 0.4e-6

[mechanics]
formulation = "3d"

[materials.al]
density = 2700.0
shear_modulus = 26.3e9
bulk_modulus = 68.6e9
yield_stress = 100e6
hardening_modulus = 500e6
electrical_conductivity = 2.5e7

[materials.cu]
density = 8960.0
shear_modulus = 48e9
bulk_modulus = 140e9
yield_stress = 200e6
electrical_conductivity = 5.8e7

[[bodies]]
name = "plate"
material = "al"
region = "plate"
fixed = [{{ group = "plate_ends", components = [0, 1, 2] }}]

[[bodies]]
name = "slug"
material = "cu"
region = "slug"
rigid = true

[geometry]
type = "geometry_3d"
file = "{GEO}"
air = "air"
shell = "shell"
mesh_sizes = {{ coil_a = 3e-3, coil_b = 3e-3, plate = 3e-3, slug = 3e-3 }}

[[geometry.coils]]
name = "a"
group = "coil_a"
turns = 4
terminals = ["a_in", "a_out"]

[[geometry.coils]]
name = "b"
group = "coil_b"
turns = 2
terminals = ["b_in", "b_out"]

[[symmetry]]
normal = [0.0, 1.0, 0.0]

[coupling]
n = 3

[em]
time_scheme = "bdf2"

[[em.sources]]
name = "sa"
type = "sine"
amplitude = {SA[0]}
frequency = {SA[1]}

[[em.sources]]
name = "sb"
type = "sine"
amplitude = {SB[0]}
frequency = {SB[1]}
phase = {SB[2]}

[[em.coils]]
name = "a"
source = "sa"

[[em.coils]]
name = "b"
source = "sb"
sign = -1

[output]
field_interval = 0.2e-6
plots = false
'''


@pytest.fixture(scope="module")
def case_dir(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("geometry3d") / "case"
    d.mkdir()
    shutil.copy(DATA / GEO, d / GEO)
    (d / "case.toml").write_text(CASE)
    return d


@pytest.fixture(scope="module")
def geometry(case_dir, tmp_path_factory):
    from pulseform.orchestrator.case.io import load_case
    from pulseform.orchestrator.mesh.geometry3d import build_geometry3d

    case, _ = load_case(case_dir)
    return case, build_geometry3d(case, tmp_path_factory.mktemp("mesh"))


def test_the_role_map_gives_the_decks_ids(geometry):
    from pulseform.orchestrator.em.model3d import em_model3d
    from pulseform.orchestrator.mesh.remesh3d import read_msh22_triangles
    from pulseform.solvers.getdp.mesh import AIR, OUTER, SHELL
    from pulseform.solvers.getdp.mesh3d import SYM_A

    case, geo = geometry
    m = geo.mesh
    assert geo.coils == {"a": 1, "b": 2} and geo.conductors == {"plate": 1, "slug": 2}
    assert set(np.unique(m.tet_tags)) == {AIR, SHELL, 101, 102, 201, 202}
    assert m.sector_deg == 180.0   # one symmetry plane: the device is twice the model
    section = (0.010 - 0.006) * 0.003   # (r1 - r0) hc of the .geo
    assert geo.coil_sections[1] == pytest.approx(section, rel=1e-12)
    assert geo.coil_sections[2] == pytest.approx(section, rel=1e-12)
    tris, tags = read_msh22_triangles(m.path)
    x = m.points
    on_plane = tris[tags == SYM_A]
    assert len(on_plane) and np.abs(x[on_plane][..., 1]).max() < 1e-12
    outer = np.linalg.norm(x[tris[tags == OUTER]], axis=2)
    assert outer.min() > 0.059   # the shell's outer sphere only
    for k in (1, 2):   # terminals on y = 0, skins of both conductors
        assert np.abs(x[tris[tags == 500 + k]][..., 1]).max() < 1e-12 and (tags == 600 + k).any()
        assert (tags == 400 + k).any()
    r_int, r_ext = geo.shell
    assert 0.045 < r_int <= 0.05 and r_ext == pytest.approx(0.06, rel=1e-9)
    model = em_model3d(case, geo)
    assert [c.direction for c in model.coils] == ["electrokinetic"] * 2 and [c.sign for c in model.coils] == [1, -1]
    assert model.circuit is None and model.symmetry_factor == 2.0
    assert [c.waveform.omega for c in model.coils] == pytest.approx([2 * np.pi * SA[1], 2 * np.pi * SB[1]])


@pytest.fixture(scope="module")
def run(case_dir, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("geometry3d_run") / "run"
    assert main(["run", str(case_dir), "--out", str(out), "--quiet"]) == 0
    return out


@pytest.mark.getdp
def test_a_users_geometry_runs_coupled_with_two_coils_a_rigid_and_a_deformable_body(run):
    m = json.loads((run / "metrics.json").read_text())
    h = np.genfromtxt(run / "history.csv", delimiter=",", names=True)
    t = h["time_s"][1:]
    assert m["status"] == "ok" and m["n_final"] == 3 and m["em_steps"] >= 20
    # (2) each coil carries its own source's current
    ia = SA[0] * np.sin(2 * np.pi * SA[1] * t)
    ib = -SB[0] * np.sin(2 * np.pi * SB[1] * t + SB[2])
    err = (np.abs(h["a_current_A"][1:] - ia).max() / SA[0], np.abs(h["b_current_A"][1:] - ib).max() / SB[0])
    # (3) ledgers
    ledgers = (m["conservation_error_rel"], m["plate_ledger_rel"], m["slug_ledger_rel"])
    # (5) Newton on the slug (free along x and z: the plane y = 0 holds y), half model: the device's impulse / 2.
    # Central differences integrate the held forces by the trapezoid rule on the mechanical steps dt (the first
    # step is a half step, the velocity now adds half a step of the current force): m v = J + dt/2 (F_last - F_1)
    mass, j = m["slug_mass_kg"], m["slug_impulse_z_Ns"] / 2
    f, dt = h["slug_force_z_N"], h["dt_s"]
    expected = j + 0.5 * dt[-1] * f[-1] - 0.5 * dt[1] * f[1]
    newton = [abs(mass * h["slug_velocity_z_m_s"][-1] - expected) / abs(j)]
    print(f"\ncurrents vs sources {err[0]:.1e} / {err[1]:.1e}; ledgers {max(ledgers):.1e}; slug m v vs impulse "
          f"{newton[0]:.1e}; energy balance {m['energy_error_rel']:.1e}; plate max |u_z| {m['plate_max_uz_mm']:.3g} mm")
    assert max(err) < 1e-8
    assert max(ledgers) < 1e-12
    assert "slug_position_y_m" not in h.dtype.names and "slug_position_x_m" in h.dtype.names
    assert newton[0] < 1e-8
    assert m["energy_error_rel"] < 1e-3   # the explicit ledger: 5.7e-5 here, 2.2e-4 on the racetrack case
    # (4) the plate's ends (the surface group plate_ends) are held; the rest moves
    with meshio.xdmf.TimeSeriesReader(run / "fields" / "two_coils_plate_3d_plate.xdmf") as reader:
        points, _ = reader.read_points_cells()
        _, data, _ = reader.read_data(reader.num_steps - 1)
    u = np.asarray(data["displacement_m"])
    ends = np.abs(np.abs(points[:, 0]) - 0.03) < 1e-12
    assert ends.any() and np.abs(u[ends]).max() == 0.0 and np.abs(u[~ends]).max() > 0.0


def _check(capsys, case_dir: Path, sets: list[str], says: str) -> str:
    return one_line_refusal(capsys, str(case_dir), sets, says)


BAD = [
    (["geometry.air=\"airr\""], "geometry.air: got 'airr', not a physical volume group of the mesh; its groups: volumes"),
    (["bodies.plate.region=\"coil_a\""], "already geometry.coils[0].group"),
    (["bodies.slug.region=\"nothing\""], "bodies[1].region: got 'nothing'"),
    (["geometry.coils=[{name=\"a\", group=\"coil_a\", turns=4}, {name=\"b\", group=\"coil_b\", turns=2, "
      "terminals=[\"b_in\", \"b_out\"]}]"], "give exactly one current path"),
    (["geometry.coils=[{name=\"a\", group=\"coil_a\", turns=4, terminals=[\"b_in\", \"a_out\"]}, {name=\"b\", "
      "group=\"coil_b\", turns=2, terminals=[\"a_in\", \"b_out\"]}]"], "is not on the boundary of the coil's volume"),
    (["bodies.slug.material=\"steel\""], "bodies[1].material"),
    (["materials.cu.electrical_conductivity=0.0"], "materials.cu.electrical_conductivity"),
    (["limits.max_cells=1000"], "limits.max_cells: the mesh has"),
    (["geometry.file=\"missing.geo\""], "geometry.file"),
    (["bodies.plate.fixed=[{group=\"no_such_face\"}]"], "bodies[0].fixed[0].group: got 'no_such_face'"),
    (["geometry.mesh_sizes={plat=1e-3}"], "geometry.mesh_sizes"),
    (["bodies.slug.moves=[1]"], "bodies[1].moves"),
    (["em.coils=[{name=\"a\", source=\"sa\"}, {name=\"c\", source=\"sb\"}]"], "em.coils[1].name"),
    (["geometry.em_order=2"], "geometry.em_order"),
    (["time.end=500.0"], "time.end: got 500 s"),   # explicit steps at the meshed bodies' stable step (estimated)
    (["geometry.mesh_sizes={plate=1e-6}"], "geometry.mesh_sizes.plate: ~"),   # estimated before meshing
    (["geometry.mesh_size_factor=1e-3"], "x geometry.mesh_size_factor: ~"),   # every size times the factor
    (["em.applied_field={type=\"dc\", magnitude=0.5, direction=[0.0, 1.0, 0.0]}"], "applied"),  # crosses y = 0
    (["em.applied_field={type=\"dc\", magnitude=0.5, direction=[0.0, 1.0]}"], "em.applied_field.direction"),
    (["coupling.load=\"pressure\"", "loads=[{type=\"pulse_exp\", body=\"slug\", surface={zmin=0.0}, amplitude=1e6, "
      "decay_time=1e-5, t_end=1e-4}]"], "loads[0].body: got 'slug', a rigid body"),   # pressure pulses load deformable bodies
]


@pytest.mark.parametrize("sets,says", BAD, ids=[f"{s[0].split('=')[0]}[{i}]" for i, (s, _) in enumerate(BAD)])
def test_bad_input_of_a_geometry_file(capsys, case_dir, sets, says):
    print(_check(capsys, case_dir, sets, says))


def test_a_cad_file_gmsh_cannot_read_and_a_builder_without_permission(capsys, case_dir, tmp_path):
    d = tmp_path / "case"
    shutil.copytree(case_dir, d)
    (d / "broken.step").write_text("ISO-10303-21;\nthis is not a STEP file\n")
    print(_check(capsys, d, ["geometry.file=\"broken.step\""], "broken.step: geometry.file: gmsh failed"))
    (d / "builder.py").write_text("raise SystemExit(3)\n")
    print(_check(capsys, d, ["geometry.file=\"builder.py\""], "allow_system_calls"))


def test_a_conductor_touching_the_outer_boundary_is_refused(capsys, tmp_path):
    d = tmp_path / "case"
    d.mkdir()
    (d / "touch.geo").write_text('''SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 0.1, 0.1, 0.1};
Box(2) = {0, 0.04, 0.04, 0.02, 0.02, 0.02};
Box(3) = {0.05, 0.04, 0.04, 0.02, 0.02, 0.02};
BooleanFragments{ Volume{1}; Delete; }{ Volume{2, 3}; Delete; }
Physical Volume("plate") = Volume In BoundingBox{-1e-6, 0.04 - 1e-6, 0.04 - 1e-6, 0.02 + 1e-6, 0.06 + 1e-6, 0.06 + 1e-6};
Physical Volume("coil") = Volume In BoundingBox{0.05 - 1e-6, 0.04 - 1e-6, 0.04 - 1e-6, 0.07 + 1e-6, 0.06 + 1e-6, 0.06 + 1e-6};
air() = Volume{:};
air() -= Volume In BoundingBox{-1e-6, 0.04 - 1e-6, 0.04 - 1e-6, 0.02 + 1e-6, 0.06 + 1e-6, 0.06 + 1e-6};
air() -= Volume In BoundingBox{0.05 - 1e-6, 0.04 - 1e-6, 0.04 - 1e-6, 0.07 + 1e-6, 0.06 + 1e-6, 0.06 + 1e-6};
Physical Volume("air") = air();
Physical Surface("c_in") = Surface In BoundingBox{0.05 - 1e-6, 0.04 - 1e-6, 0.04 - 1e-6, 0.05 + 1e-6, 0.06 + 1e-6, 0.06 + 1e-6};
Physical Surface("c_out") = Surface In BoundingBox{0.07 - 1e-6, 0.04 - 1e-6, 0.04 - 1e-6, 0.07 + 1e-6, 0.06 + 1e-6, 0.06 + 1e-6};
MeshSize{ PointsOf{ Volume{:}; } } = 0.02;
''')
    text = CASE.replace(f'file = "{GEO}"', 'file = "touch.geo"').replace('shell = "shell"\n', "")
    text = text.replace("mesh_sizes = { coil_a = 3e-3, coil_b = 3e-3, plate = 3e-3, slug = 3e-3 }\n", "")
    text = text.replace('''[[bodies]]
name = "slug"
material = "cu"
region = "slug"
rigid = true
''', "").replace('fixed = [{ group = "plate_ends", components = [0, 1, 2] }]\n', "")
    head, _, rest = text.partition("[[geometry.coils]]")
    text = head + '''[[geometry.coils]]
name = "a"
group = "coil"
turns = 1
terminals = ["c_in", "c_out"]

[[symmetry]]
normal = [0.0, 1.0, 0.0]

[em]
time_scheme = "bdf2"
current = { amplitude = 1e3, beta = 0.0, omega = 1e5 }
'''
    (d / "case.toml").write_text(text)
    print(_check(capsys, d, [], "bodies[0].region: the group touches the outer boundary"))


def test_a_cad_file_gets_a_group_per_volume_and_surface(tmp_path):
    """A STEP file (written here by gmsh's OpenCASCADE: two boxes, no physical groups) is meshed by the runner
    with one group per volume and per surface (its CAD label or volume_<tag>): what a role map then names."""
    from types import SimpleNamespace

    from pulseform.orchestrator.mesh.gmsh_file import mesh_file3d, read_groups
    from pulseform.solvers.getdp.mesh import gmsh_session

    step = tmp_path / "part.step"
    with gmsh_session("cad") as gmsh:
        gmsh.model.occ.addBox(0, 0, 0, 0.1, 0.1, 0.1)
        gmsh.model.occ.addBox(0.03, 0.03, 0.03, 0.02, 0.02, 0.02)
        gmsh.model.occ.synchronize()
        gmsh.write(str(step))
    g = SimpleNamespace(file=str(step), parameters=None, mesh_sizes={})
    raw = read_groups(mesh_file3d(g, tmp_path / "mesh"), "part.step")
    print("\n" + raw.listing())
    assert len(raw.volumes) == 2 and len(raw.surfaces) >= 12   # the fragment: inner box and the air around it
    counts = sorted(int((raw.tet_group == v).sum()) for v in raw.volumes)
    assert counts[0] > 0


RING_CASE = '''
[case]
name = "ring_cut_disk"
kind = "coupled"

[time]
end = 2e-6

[mechanics]
formulation = "3d"

[materials.al]
density = 2700.0
shear_modulus = 26.3e9
bulk_modulus = 68.6e9
yield_stress = 100e6
electrical_conductivity = 3.5e7

[[bodies]]
name = "disk"
material = "al"
region = "disk"

[geometry]
type = "geometry_3d"
file = "ring_cut_disk.geo"
air = "air"
shell = "shell"
mesh_sizes = {{ ring = 2e-3, disk = 4e-3 }}

[[geometry.coils]]
name = "ring"
group = "ring"
turns = 1
{path}

[em]
time_scheme = "bdf2"
current = {{ amplitude = 1e4, beta = 1e4, omega = 1e5 }}
'''


@pytest.mark.getdp
def test_a_closed_coil_by_its_cut_equals_the_azimuthal_current(tmp_path):
    """A closed ring whose current path is a cut surface (``[[geometry.coils]] cut``, crossing it along +y: +e_phi
    at the cut) and the same ring with the azimuthal direction (``axis = [0, 0]``), same mesh and section, 2 BDF2
    steps of 1 us: the disk's axial force agrees within 5e-3 of its peak. The cut's P1 direction field is
    azimuthal to O(h/R) (docs/getdp.md): measured 5.7e-3 with 3 mm ring elements, 8.4e-4 with the 2 mm here.
    The cut's area is the coil's section: the rectangle (r1 - r0)(z1 - z0) = 2e-5 m^2 to 1e-9."""
    from pulseform.orchestrator.case.io import load_case
    from pulseform.orchestrator.em.model3d import em_model3d
    from pulseform.orchestrator.mesh.geometry3d import build_geometry3d
    from pulseform.solvers.getdp.solver3d import coil_section_from_mesh, solve_transient3d

    forces = {}
    for kind, path in (("cut", 'cut = "cut"\ncut_direction = [0.0, 1.0, 0.0]'), ("axis", "axis = [0.0, 0.0]")):
        d = tmp_path / kind
        d.mkdir()
        shutil.copy(DATA / "ring_cut_disk.geo", d / "ring_cut_disk.geo")
        (d / "case.toml").write_text(RING_CASE.format(path=path))
        case, _ = load_case(d)
        geo = build_geometry3d(case, d / "mesh")
        model = em_model3d(case, geo)
        if kind == "cut":
            assert model.coils[0].direction == "cut" and geo.coil_sections[1] == pytest.approx(2e-5, rel=1e-9)
        else:
            print(f"\nmeridian section of the meshed ring {coil_section_from_mesh(geo.mesh, 1):.6e} m^2")
            model.coils[0].section = 2e-5   # the same section as the cut's: only the direction fields differ
        res = solve_transient3d(model, geo.mesh, 2e-6, 2, d / "run", time_scheme="bdf2", element_output="none")
        forces[kind] = res.conductor_force[:, 0, 2]
    diff = np.abs(forces["cut"] - forces["axis"]).max() / np.abs(forces["axis"]).max()
    print(f"\ndisk F_z cut {forces['cut']} vs azimuthal {forces['axis']} N: {diff:.1e}")
    assert forces["axis"][-1] > 0 and diff < 5e-3


@pytest.mark.getdp
def test_an_applied_field_alone_on_a_users_geometry(tmp_path):
    """[em.applied_field] on a 3D geometry file without coils: the ring of ring_cut_disk.geo as a fixed conductor of
    negligible conductivity (1e-3 S/m: no current of its own), the disk a body, a uniform axial field of 0.2 T
    switched on at t = 0 (dc). The case's field reaches the 3D model (magnitude, direction, time function), and 2
    BDF2 steps of 1 us give the disk eddy currents (Joule power > 0) opposing the rising field, so that the field
    squeezes the disk: the radial force sum of f . e_r V over its tetrahedra is inward, and the in-plane resultant
    vanishes by the axial symmetry (|F_x|, |F_y| below 2 % of the summed radial force on this free mesh). The
    analytic diffusion checks of the field are tests/getdp/test_applied_field.py."""
    from pulseform.orchestrator.case.io import load_case
    from pulseform.orchestrator.em.model3d import em_model3d
    from pulseform.orchestrator.mesh.geometry3d import build_geometry3d
    from pulseform.solvers.getdp.solver3d import solve_transient3d

    d = tmp_path / "case"
    d.mkdir()
    shutil.copy(DATA / "ring_cut_disk.geo", d / "ring_cut_disk.geo")
    text = RING_CASE.format(path="").replace("""[[geometry.coils]]
name = "ring"
group = "ring"
turns = 1
""", """[[geometry.conductors]]
name = "ring"
group = "ring"
material = "insulator"
""").replace("[[bodies]]", """[materials.insulator]
density = 2700.0
shear_modulus = 26.3e9
bulk_modulus = 68.6e9
yield_stress = 100e6
electrical_conductivity = 1e-3

[[bodies]]""").replace("current = { amplitude = 1e4, beta = 1e4, omega = 1e5 }",
             'applied_field = { type = "dc", magnitude = 0.2, direction = [0.0, 0.0, 1.0] }')
    (d / "case.toml").write_text(text)
    case, _ = load_case(d)
    geo = build_geometry3d(case, d / "mesh")
    model = em_model3d(case, geo)
    assert not model.coils and model.applied_field.B0 == 0.2 and tuple(model.applied_field.direction) == (0, 0, 1)
    res = solve_transient3d(model, geo.mesh, 2e-6, 2, d / "run", time_scheme="bdf2")
    rows = res.element_tags == 201
    f = res.force_density[-1][rows] * geo.mesh.volumes(res.elements[rows])[:, None]
    c = geo.mesh.centroids(res.elements[rows])
    e_r = c[:, :2] / np.linalg.norm(c[:, :2], axis=1)[:, None]
    radial = float(np.einsum("ij,ij->", f[:, :2], e_r))
    print(f"\ndisk: Joule power {res.conductor_power[-1, 0]:.4g} W, radial force {radial:.4g} N, in-plane resultant "
          f"{f[:, 0].sum():.3g}, {f[:, 1].sum():.3g} N")
    assert res.conductor_power[-1, 0] > 0 and radial < 0
    assert max(abs(f[:, 0].sum()), abs(f[:, 1].sum())) < 0.02 * abs(radial)


# slow (two more runs of the user's geometry; in the default tier: the loop's iterate and adaptive options,
# tests/coupling/test_loop_options.py and test_loop_fake.py; the 3D load's state put back into a new getdp process,
# tests/coupling/test_case_racetrack_remesh.py::test_sigint_after_the_remesh_then_resume_equals_the_uninterrupted_run)
@pytest.mark.slow
@pytest.mark.getdp
def test_iterated_and_adaptive_coupling_on_a_users_geometry(case_dir, run, tmp_path):
    """[coupling] iterate and adaptive on the 3D path. Iterated: each EM step is redone on its end geometry from
    the restored EM state (the persistent getdp's vectors put back, a new process); in 0.05 us the plate moves
    ~1e-11 m, so the redone step must give the first run's forces (the plain run above, same steps) to 1e-9 and
    converge in 2 iterations. Adaptive: n changes from the force's rate of change and the run completes with
    its ledger at round-off."""
    plain = np.genfromtxt(run / "history.csv", delimiter=",", names=True)
    out = tmp_path / "iterated"
    assert main(["run", str(case_dir), "--out", str(out), "--quiet", "--set", "coupling.iterate=true",
                 "--set", "time.end=0.05e-6", "--set", "output.field_interval=0.05e-6", "--set", "output.plots=false"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    h = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    n = len(h)
    assert m["coupling_iterations_max"] == 2 and m["coupling_unconverged_steps"] == 0
    for col in ("plate_force_z_N", "slug_force_z_N", "a_current_A"):
        np.testing.assert_allclose(h[col][1:n], plain[col][1:n], rtol=1e-9, atol=1e-12 * np.abs(plain[col]).max())
    out = tmp_path / "adaptive"
    assert main(["run", str(case_dir), "--out", str(out), "--quiet", "--set", "coupling.adaptive=true",
                 "--set", "coupling.n_max=12", "--set", "time.end=0.1e-6", "--set", "output.field_interval=0.1e-6"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    print(f"\nadaptive: {m['em_steps']:.0f} EM steps, final n {m['n_final']:.0f}; ledger {m['conservation_error_rel']:.1e}")
    assert m["status"] == "ok" and m["conservation_error_rel"] < 1e-12 and m["n_final"] != 3


def test_a_surface_group_holds_a_ten_node_bodys_edge_nodes_on_it(case_dir, tmp_path):
    """``[[bodies.fixed]]`` by a physical surface group on a ten-node body (issue 34 item 4): every node of the body
    on the group's triangles is held -- their vertices and the edge nodes at the middles of their edges -- and no
    other (the edge nodes are no EM nodes: the group's node list alone would leave them free)."""
    from pulseform.orchestrator.case.io import load_case
    from pulseform.orchestrator.run.participants3d import participants_3d

    case, _ = load_case(case_dir, ["bodies.plate.element='tet10'"])
    solver, rigid, load, _, geo = participants_3d(case, tmp_path)
    load.close()
    body = solver.bodies["plate"]
    x = geo.mesh.points
    tri = geo.surface_tris["plate_ends"]
    edges = np.unique(np.sort(tri[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1), axis=0)
    on_group = np.concatenate([x[np.unique(tri)], 0.5 * (x[edges[:, 0]] + x[edges[:, 1]])])
    scale = float(np.abs(x).max())
    dist = np.min(np.linalg.norm(body.X0[:, None, :] - on_group[None, :, :], axis=2), axis=1)
    expected = dist <= 1e-9 * scale
    held = body.constrained_mask().all(axis=1)
    edge = np.arange(len(body.X0)) >= body.n_vertices
    print(f"\nten-node plate: {held.sum()} held nodes ({(held & edge).sum()} edge nodes) of {len(held)}")
    assert (held & edge).sum() > 0 and np.array_equal(held, expected)
