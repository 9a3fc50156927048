"""The 3D air remesh with the EM state carried (orchestrator/em/remesh3d.py, orchestrator/mesh/remesh3d.py,
solvers/getdp/state_carry3d.py) on the coarse racetrack (sizes x 2; the case file on the 3D geometry path,
tests/coupling/racetrack_coarse.py), EM only: the bodies stay where they
are (a mechanics that does not move), BDF2 steps of 1 us on the capacitor bank, the persistent getdp.

References:
(1) the run with a remesh forced before step ``K`` against the run without: after the remesh only the air
    differs, so the force histories differ by the mesh-to-mesh air difference; its size is measured by a
    third run on an air meshed again from scratch before the first step (two air meshes of equal size,
    no state carried): the forced remesh must stay within 2x that difference (it cannot be exactly 0:
    the air is another mesh), and far from the force itself;
(2) GetDP post-processes the carried state on the new mesh and the old state on the old mesh: B and
    j = -sigma Dt a (from x_n and x_{n-1}) on every conductor tetrahedron, matched by centroid: the
    conductor tetrahedra and their edges are the same, so they agree to round-off (1e-9 relative to
    the largest value; the .res text carries 17 digits);
(3) the per-body ledgers (nodal forces vs the tetrahedra's integral) stay at round-off after a remesh.
"""
import re
from pathlib import Path

import numpy as np
import pytest

from pulseform.orchestrator.em.remesh3d import RemeshingGetDPLoad3D
from pulseform.solvers.getdp.runner import run_getdp
from pulseform.solvers.getdp.solver3d import model_numbers
from pulseform.solvers.getdp.stepper3d import read_res_vector, write_res_vector

from .racetrack_coarse import coarse_participants

pytestmark = pytest.mark.getdp

STEPS, K, DT = 4, 3, 1e-6


class Still:
    """A mechanics that does not move: the bodies at their reference positions."""

    def __init__(self, load):
        self.pos = {b.name: load.mesh.points[b.body_to_em].copy() for b in load.bodies}

    def positions(self):
        return self.pos


def _run(work: Path, remesh_before: int | None, post: list | None = None) -> list[dict]:
    """STEPS EM steps of the coarse racetrack's load; the air meshed again before step ``remesh_before``
    (1: before the first step, from scratch; None: never); ``post`` receives GetDP's conductor fields
    of the state just before and just after that remesh."""
    load = coarse_participants(work)[2]
    assert isinstance(load, RemeshingGetDPLoad3D)
    mech = Still(load)
    rows = []
    try:
        for k in range(1, STEPS + 1):
            t0, t1 = (k - 1) * DT, k * DT
            if k == remesh_before:
                if post is not None:
                    load.state = load.stepper.complete_state(load.state)
                    proc = load.stepper.proc
                    post.append(_fields(load, work / "post_old", pre=proc.run_dir / "em.pre", msh=proc.run_dir / "mesh.msh"))
                load.remesh_now(t0, mech.positions())
                if post is not None:
                    post.append(_fields(load, work / "post_new"))
            rows.append(load.load(t0, t1, 0.5 * (t0 + t1), mech).values)
    finally:
        load.close()
    return rows


def _fields(load, folder: Path, **where) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """GetDP's B (T) and j (A/m^2, from x_{n-1} and x_n) on the conductor tetrahedra of the load's mesh for
    its (complete) state: name -> (centroids (m), values), one row per tetrahedron."""
    st = load.state
    dofs = load._edge_dofs(load.mesh, folder, **where)   # writes calib.pro and em.pre there
    dofdata, t, x_n = read_res_vector(st.res_path)
    blocks = []
    for tt, x in ((t - st.dt_prev, st.x_prev), (t, x_n)):
        for s in range(dofs.system + 1):   # systems before A (the coils' direction): zeros, unused here
            n = dofs.n_dofs if s == dofs.system else int(read_res_vector(folder / f"calib_{s}.res")[2].size)
            v = x if s == dofs.system else np.zeros(n)
            blocks.append(write_res_vector(folder / "one.res", str(s), tt, v).read_text())
    (folder / "state.res").write_text(blocks[0] + "".join(b.split("$EndResFormat\n", 1)[1] for b in blocks[1:]))
    (folder / "bj.pro").write_text((folder / "calib.pro").read_text() + (
        'PostOperation { { Name PF_BJ; NameOfPostProcessing EM_a3D; Operation {\n'
        '  Print[ b, OnElementsOf Vol_C_Mag, Depth 0, Format Gmsh, File "b.pos" ];\n'
        '  Print[ j, OnElementsOf Vol_C_Mag, Depth 0, Format Gmsh, File "j.pos" ]; } } }\n'))
    numbers, _ = model_numbers(load.model, load.mesh)
    run_getdp(folder / "bj.pro", where.get("msh", load.mesh.path), folder, resolution="EM_Persistent3D",
              numbers=numbers, post_operation="PF_BJ", extra_args=["-res", str(folder / "state.res")],
              log_name="bj.log")
    out = {}
    for name in ("b", "j"):
        recs = re.findall(r"V[A-Z]\(([^)]*)\)\{([^}]*)\}", (folder / f"{name}.pos").read_text())
        xyz = np.array([r[0].split(",") for r in recs], float).reshape(len(recs), -1, 3).mean(axis=1)
        val = np.array([r[1].split(",") for r in recs], float).reshape(len(recs), -1, 3)[:, -1]
        out[name] = (xyz, val)
    return out


def _force(rows: list[dict]) -> np.ndarray:
    """(steps, 2): GetDP's z-force (N) on the sheet and on the die per step."""
    return np.array([[r["sheet_getdp_force_z_N"], r["die_getdp_force_z_N"]] for r in rows])


def test_forced_remesh_of_an_undeformed_mesh(tmp_path):
    post: list = []
    plain = _force(_run(tmp_path / "plain", None))
    rows = _run(tmp_path / "forced", K, post)
    forced = _force(rows)
    scratch = _force(_run(tmp_path / "scratch", 1))
    scale = np.abs(plain).max(axis=0)
    d_forced = np.abs(forced - plain).max(axis=0) / scale
    d_mesh = np.abs(scratch - plain).max(axis=0) / scale
    before = np.abs(forced[:K - 1] - plain[:K - 1]).max()
    old, new = post
    dev = {}
    for name in ("b", "j"):
        (c0, v0), (c1, v1) = old[name], new[name]
        o0, o1 = np.lexsort(np.round(c0 / 1e-9).T), np.lexsort(np.round(c1 / 1e-9).T)
        assert len(c0) == len(c1) and np.abs(c0[o0] - c1[o1]).max() < 1e-12
        dev[name] = np.abs(v0[o0] - v1[o1]).max() / np.abs(v0).max()
    ledger = max(max(r["sheet_ledger_rel"], r["die_ledger_rel"]) for r in rows)
    print(f"\nforce (sheet, die) vs no remesh: forced remesh before step {K} {d_forced}, air meshed from scratch "
          f"{d_mesh}; conductor fields after/before the remesh: B {dev['b']:.1e}, j {dev['j']:.1e}; ledger "
          f"{ledger:.1e}; max |F_z| {scale} N")
    assert before == 0.0                                   # identical runs until the remesh
    assert np.all(d_forced > 0) and np.all(d_forced <= 2 * d_mesh) and np.all(d_mesh < 0.05)
    assert dev["b"] < 1e-9 and dev["j"] < 1e-9
    assert ledger < 1e-12


def test_a_failed_remesh_freezes_the_em_mesh():
    """The rule of orchestrator/em/remesh3d.py: a broken air mesh is meshed again; when that fails
    (RemeshFailed: gmsh, or a new mesh not above the threshold) the EM mesh freezes at the last valid one
    (no getdp: a fake mover that breaks at its third call and a remesh that fails)."""
    from pulseform.orchestrator.em.participant3d import ConductorBody3D
    from pulseform.orchestrator.em.remesh3d import RemeshFailed
    from pulseform.orchestrator.mesh.motion import MeshQualityError

    points = np.zeros((4, 3))

    class Mover:
        calls, last_min_quality = 0, 0.5

        def moved(self, u):
            Mover.calls += 1
            if Mover.calls >= 3:
                raise MeshQualityError("tetrahedron 7 inverted")
            return points + u

    tried = []

    def fail(t0, positions):
        tried.append(t0)
        raise RemeshFailed("the new air mesh's worst quality 1e-05 is not above the threshold 0.0001")

    load = RemeshingGetDPLoad3D.__new__(RemeshingGetDPLoad3D)
    load.mesh = type("M", (), {"points": points})()
    load.bodies = [ConductorBody3D("sheet", 201, None, np.arange(4))]
    load.mover, load.min_quality, load._moved = Mover(), 1.0, None
    load.timers, load.impulse_device = {"mesh_motion_s": 0.0}, 0.0
    load.freeze, load.frozen_at, load.freeze_reason, load._last_valid = True, None, "", points.copy()
    load.remesh, load.remeshes, load.max_remeshes, load.remesh_now = True, 0, 50, fail
    mech = type("Mech", (), {"positions": lambda self: {"sheet": np.full((4, 3), self.u)}})
    for k, u in enumerate((1e-4, 2e-4, 3e-4, 4e-4)):
        m = mech()
        m.u = u
        load.follow(float(k), m)
    assert tried == [2.0] and load.frozen_at == 2.0   # one remesh tried, then frozen at step 1's mesh
    np.testing.assert_array_equal(load._moved[1], np.full((4, 3), 2e-4))


def test_air_remesh_keeps_conductors_coil_shell_and_groups(tmp_path):
    """remesh_air3d on the coarse racetrack's undeformed EM mesh (the builder and gmsh only): every non-air tetrahedron and
    every surface element off the air's plane faces is kept node for node in the same order (so GetDP's
    low-to-high edge orientation of the conductors is kept), the new air is valid and fills the same
    volume (the sphere cut by the kept parts: its volume to round-off), the planes' faces stay in group 14."""
    from pulseform.orchestrator.mesh.motion3d import tet_quality
    from pulseform.orchestrator.mesh.remesh3d import read_msh22_triangles, remesh_air3d
    from pulseform.orchestrator.mesh.geometry3d import build_geometry3d
    from pulseform.solvers.getdp.mesh3d import SYM_A

    from .racetrack_coarse import coarse_case

    geo = build_geometry3d(coarse_case(), tmp_path)
    m = geo.mesh
    assert len(geo.planes) == 2   # x = 0 and y = 0
    new, o2n = remesh_air3d(m, m.points, tmp_path / "new.msh", [(p.point, p.normal) for p in geo.planes])
    air0, air1 = m.tet_tags == 1, new.tet_tags == 1
    np.testing.assert_array_equal(o2n[m.tets[~air0]], new.tets[~air1])
    np.testing.assert_array_equal(m.tet_tags[~air0], new.tet_tags[~air1])
    kept = o2n >= 0
    assert np.all(np.diff(o2n[kept]) > 0) and np.array_equal(new.points[o2n[kept]], m.points[kept])
    assert tet_quality(new.points, new.tets[air1]).min() > 0.01
    assert abs(m.volumes(np.flatnonzero(air0)).sum() / new.volumes(np.flatnonzero(air1)).sum() - 1) < 1e-12
    t0, g0 = read_msh22_triangles(m.path)
    t1, g1 = read_msh22_triangles(new.path)
    for g in np.unique(g0):
        if g != SYM_A:
            np.testing.assert_array_equal(o2n[t0[g0 == g]], t1[g1 == g])
    area = lambda p, t: 0.5 * np.linalg.norm(np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]), axis=1).sum()
    assert abs(area(new.points, t1[g1 == SYM_A]) / area(m.points, t0[g0 == SYM_A]) - 1) < 1e-12
