"""Several conductor bodies in one EM mesh: a die over the sheet (a), a collar around the tube (b),
the planar coil + blank + 130° die (c). Geometry and remeshing without getdp; short coupled runs on
GetDP + DOLFINx (marker getdp)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pulseform.orchestrator.case.model import (FlatCoilSheet, OuterTube, PlanarCoilBlankDie, SheetDie, SolenoidTube)
from pulseform.orchestrator.em.participant import ConductorBody, GetDPLoad
from pulseform.orchestrator.mesh.em_geometry import build_em_geometry, sheet_die_polygon
from pulseform.orchestrator.mesh.shared import conductor_submesh
from pulseform.orchestrator.coupling.transfer import cell_volumes
from pulseform.solvers.getdp import Coil, Conductor, EMModel
from pulseform.solvers.getdp.mesh import AXIS
from warm_cli import pulseform_cli

REPO = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).with_name("pulseform"))

DIE = SheetDie(cavity_radius=25e-3, cavity_depth=3e-3, outer_radius=45e-3, height=12e-3, gap=0.2e-3,
               entry_radius=1.5e-3, mesh_size=2e-3)
SHEET = FlatCoilSheet(type="flat_coil_sheet", turns=3, coil_inner_radius=10e-3, turn_width=4e-3,
                      turn_height=3e-3, turn_gap=1e-3, coil_gap=1.5e-3, sheet_radius=40e-3,
                      sheet_thickness=1e-3, air_radius=0.1, shell_radius=0.13, mesh_size_sheet=1e-3,
                      mesh_size_coil=2e-3, mesh_size_air=0.02, die=DIE)
TUBES = SolenoidTube(type="solenoid_tube", turns=4, coil_inner_radius=12e-3, turn_width=3e-3,
                     turn_height=3e-3, turn_gap=1e-3, tube_inner_radius=17e-3, tube_thickness=1.5e-3,
                     tube_length=40e-3, air_radius=0.1, shell_radius=0.13, mesh_size_tube=1e-3,
                     mesh_size_coil=2e-3, mesh_size_air=0.02,
                     outer_tube=OuterTube(inner_radius=19e-3, thickness=5e-3, length=20e-3, mesh_size=1.5e-3))
DIE_POLY = ((0.0, -0.04), (0.145, -0.04), (0.145, -0.00015), (0.075, -0.00015), (0.06, -0.02), (0.0, -0.02))
PLANAR = PlanarCoilBlankDie(type="planar_coil_blank_die", turns=3, coil_inner_x=0.0, turn_width=10e-3,
                            turn_height=5e-3, turn_gap=2e-3, coil_gap=1e-3, blank_half_width=0.14,
                            blank_thickness=1e-3, die=DIE_POLY, air_radius=0.25, shell_radius=0.3,
                            mesh_size_blank=2e-3, mesh_size_die=5e-3, mesh_size_coil=3e-3, mesh_size_air=0.05)


def shoelace(p) -> float:
    p = np.asarray(p, float)
    return 0.5 * float(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))


def ring_volume(p) -> float:
    """2π ∫ r dA of a polygon (Pappus: 2π · centroid radius · area), exact for straight edges."""
    p = np.asarray(p, float)
    x, y, xn, yn = p[:, 0], p[:, 1], np.roll(p[:, 0], -1), np.roll(p[:, 1], -1)
    cross = x * yn - xn * y
    return 2 * math.pi * float(np.sum((x + xn) * cross) / 6.0)


@pytest.fixture(scope="module")
def sheet_die():
    return build_em_geometry(SHEET)


def test_die_region_is_the_polygon(sheet_die):
    """The die region has exactly the polygon's area and ring volume; sheet and die share no node."""
    m, reg = sheet_die.mesh, sheet_die.regions
    assert set(reg) == {"coil", "workpiece", "die"} and sheet_die.conductor_roles() == ["workpiece", "die"]
    poly = sheet_die_polygon(SHEET)
    assert m.region_area(reg["die"]) == pytest.approx(shoelace(poly), rel=1e-12)
    sub = conductor_submesh(m, reg["die"])
    assert cell_volumes(sub.points, sub.cells, axisymmetric=True).sum() == pytest.approx(ring_volume(poly), rel=1e-12)
    work = conductor_submesh(m, reg["workpiece"])
    assert not set(work.em_nodes) & set(sub.em_nodes)
    # the die's axis edge (r = 0, from the cavity bottom to its top) is on the a = 0 line
    axis_nodes = set(m.lines[m.line_tags == AXIS].ravel())
    on_axis = sub.em_nodes[np.abs(sub.points[:, 0]) < 1e-12]
    assert len(on_axis) >= 2 and set(on_axis) <= axis_nodes


def test_outer_tube_and_planar_regions():
    t = build_em_geometry(TUBES)
    for role, (r0, r1, length) in {"workpiece": (17e-3, 18.5e-3, 40e-3), "outer_tube": (19e-3, 24e-3, 20e-3)}.items():
        sub = conductor_submesh(t.mesh, t.regions[role])
        want = math.pi * (r1 ** 2 - r0 ** 2) * length
        assert cell_volumes(sub.points, sub.cells, axisymmetric=True).sum() == pytest.approx(want, rel=1e-12), role
    p = build_em_geometry(PLANAR)
    assert p.planar and p.conductor_roles() == ["workpiece", "die"]
    assert p.mesh.region_area(p.regions["workpiece"]) == pytest.approx(0.14e-3, rel=1e-12)
    assert p.mesh.region_area(p.regions["die"]) == pytest.approx(shoelace(DIE_POLY), rel=1e-12)
    axis_nodes = np.unique(p.mesh.lines[p.mesh.line_tags == AXIS].ravel())
    assert np.abs(p.mesh.points[axis_nodes, 0]).max() < 1e-12  # the symmetry plane x = 0 carries a = 0
    assert p.mesh.points[:, 0].min() > -1e-12  # half model


class _Moved:
    """A mechanics stand-in: node positions per body."""

    def __init__(self, positions):
        self._p = positions

    def positions(self):
        return self._p


@pytest.mark.parametrize("planar", [False, True], ids=["axisymmetric", "planar"])
def test_two_remeshes_keep_every_body_on_its_own_nodes(tmp_path, sheet_die, planar):
    """Remesh twice around a bulged sheet (blank) and a shifted die: each body's mechanical nodes
    are EM nodes at exactly their positions, with their own triangles (regression: the second remesh
    used to look the nodes up in an unsorted index). Planar: the blank sags into the groove."""
    geo = build_em_geometry(PLANAR) if planar else sheet_die
    m = geo.mesh
    bodies = []
    for role, name in (("workpiece", "sheet"), ("die", "die")):
        sub = conductor_submesh(m, geo.regions[role])
        perm = np.random.default_rng(1).permutation(len(sub.em_nodes))  # mechanical node order differs
        bodies.append(ConductorBody(name, geo.regions[role], sub, sub.em_nodes[perm]))
    wave = {"I0": 1.0, "beta": 0.0, "omega": 1.0}
    shell = (0.25, 0.3) if planar else (0.1, 0.13)
    model = EMModel(axisymmetric=not planar, coils=[Coil(turns=3, waveform=wave)],
                    conductors=[Conductor(sigma=1e7), Conductor(sigma=1e6)], shell=shell)
    load = GetDPLoad(geo, model, tmp_path, bodies, sizes=(3e-3, 0.05) if planar else (2e-3, 0.02))
    X = {b.name: m.points[b.body_to_em].copy() for b in bodies}
    width, sign = (0.07, -1.0) if planar else (40e-3, 1.0)  # planar: the sag stays over the groove
    for amp in (0.3e-3, 0.6e-3):
        pos = {}
        r = np.minimum(X["sheet"][:, 0] / width, 1.0)
        pos["sheet"] = X["sheet"] + np.stack([0 * r, sign * amp * np.cos(0.5 * math.pi * r) ** 2], axis=1)
        pos["die"] = X["die"] + np.array([0.0, sign * 0.25 * amp])
        load._remesh(pos)
        mesh = load.geometry.mesh
        for b in load.bodies:
            assert np.array_equal(mesh.points[b.body_to_em], pos[b.name]), b.name
            rows = np.flatnonzero(mesh.tri_tags == b.tag)
            assert set(np.unique(mesh.triangles[rows])) == set(b.body_to_em), b.name
            assert np.array_equal(mesh.points[b.sub.em_nodes], b.sub.points)
    assert load.remeshes == 2
    assert load.material[load.bodies[0].body_to_em] == pytest.approx(X["sheet"], abs=0.0)


def _run(case: str, out: Path, *extra: str) -> dict:
    """A short run of ``cases/<case>``; its metrics. Without pictures: the tests read metrics and history.csv (a
    picture group that fails is only logged, so drawing them tested nothing here)."""
    r = pulseform_cli(["run", str(REPO / "cases" / case), "--out", str(out), "--quiet",
                       "--set", "time.end=2e-6", "--set", "output.field_interval=1e-6", "--set", "output.plots=false",
                       *extra])
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads((out / "metrics.json").read_text())


@pytest.mark.getdp
def test_die_and_sheet_free_momentum_equals_impulse(tmp_path):
    """cases/emf_sheet_die with both bodies free: the eddy-current forces on sheet and die are the
    only external forces, so Σ m v_z over both bodies equals the impulse the loop delivered
    (rebuilt from history.csv with central differences' weights), and the ledger holds over both."""
    out = tmp_path / "free"
    m = _run("emf_sheet_die", out, "--set", "bodies.sheet.fixed=[]", "--set", "bodies.die.fixed=[]")
    assert m["conservation_error_rel"] <= 1e-10
    h = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    forces, dts = [], []
    for row in h[1:]:
        forces += [row["force_y_N"]] * int(row["substeps"])
        dts += [row["dt_s"]] * int(row["substeps"])
    forces, dts = np.array(forces), np.array(dts)
    expected = float(np.sum(forces * 0.5 * (np.concatenate([[0.0], dts[:-1]]) + dts)))
    got = h["sheet_momentum_y_Ns"][-1] + h["die_momentum_y_Ns"][-1]
    assert got == pytest.approx(expected, rel=1e-9)
    # the die, behind the sheet, is pushed too (same direction, away from the coil) but far less
    assert 0.0 < h["die_momentum_y_Ns"][-1] < 0.2 * h["sheet_momentum_y_Ns"][-1]


@pytest.mark.getdp
def test_planar_forces_scale_with_the_depth(tmp_path):
    """Plane strain: GetDP's forces are per metre of depth and the mechanics' thickness multiplies
    them and the masses alike, so the motion is the same and the impulse scales exactly."""
    a = _run("emf_corner_fill", tmp_path / "t1", "--set", "geometry.mesh_size_coil=3e-3",
             "--set", "geometry.mesh_size_die=5e-3", "--set", "geometry.mesh_size_air=0.05")
    b = _run("emf_corner_fill", tmp_path / "t2", "--set", "geometry.mesh_size_coil=3e-3",
             "--set", "geometry.mesh_size_die=5e-3", "--set", "geometry.mesh_size_air=0.05",
             "--set", "mechanics.thickness=2.5")
    assert a["conservation_error_rel"] <= 1e-10 and b["conservation_error_rel"] <= 1e-10
    assert b["force_impulse_Ns"] == pytest.approx(2.5 * a["force_impulse_Ns"], rel=1e-9)
    assert b["blank_max_uy_mm"] == pytest.approx(a["blank_max_uy_mm"], rel=1e-9)
    assert a["force_impulse_z_Ns"] < 0.0  # the blank is pushed away from the coil, into the die


def test_physical_groups_are_named(tmp_path, sheet_die):
    """One gmsh model per case with named groups; the names reach the MSH file GetDP reads."""
    from pulseform.solvers.getdp.mesh import write_msh22

    assert sheet_die.mesh.names == {1: "air", 2: "shell", 11: "axis", 12: "outer", 101: "coil", 201: "workpiece",
                                    202: "die"}
    text = write_msh22(sheet_die.mesh.with_points(sheet_die.mesh.points), tmp_path / "m.msh").read_text()
    block = text[text.index("$PhysicalNames"):text.index("$EndPhysicalNames")]
    assert '2 202 "die"' in block and '1 11 "axis"' in block and block.splitlines()[1] == "7"
    import meshio

    assert set(meshio.read(tmp_path / "m.msh").field_data) == set(sheet_die.mesh.names.values())


@pytest.mark.slow
@pytest.mark.getdp
def test_kill9_then_resume_with_two_bodies(tmp_path):
    """(Slow, ~15 s: a second kill -9 resume; the default tier's is
    tests/coupling/test_coupled_getdp.py::test_kill9_at_an_em_step_then_resume, and the free two-body run's
    physics is test_die_and_sheet_free_momentum_equals_impulse.)
    emf_sheet_die with both bodies free: kill -9 after the first checkpoint, resume, and every
    physics metric equals an uninterrupted run's (issue 5: <= 1e-12 relative). (Remeshing is not
    forced here: the worst element of this mesh does not move, so the quality threshold cannot
    trigger it; the two-body remesh itself is checked by the test above.)"""
    import signal
    import time

    extra = ["--set", "time.end=3e-6", "--set", "output.field_interval=1e-6", "--set", "bodies.sheet.fixed=[]",
             "--set", "bodies.die.fixed=[]"]
    args = lambda out: [EXE, "run", str(REPO / "cases/emf_sheet_die"), "--out", str(out), "--quiet", *extra]  # noqa: E731
    ref = subprocess.run(args(tmp_path / "ref"), capture_output=True, text=True)
    assert ref.returncode == 0, ref.stderr[-3000:]
    out = tmp_path / "killed"
    proc = subprocess.Popen(args(out), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 300
    while not (out / "checkpoint.npz").exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.005)
    time.sleep(0.3)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    if (out / "metrics.json").exists():
        pytest.skip("the run finished before it could be killed")
    r = subprocess.run(args(out) + ["--resume"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    got = json.loads((out / "metrics.json").read_text())
    want = json.loads((tmp_path / "ref/metrics.json").read_text())
    for k, v in want.items():
        if k.endswith("_s") and k != "end_time_s":
            continue
        assert got[k] == pytest.approx(v, rel=1e-12, abs=1e-300), k
