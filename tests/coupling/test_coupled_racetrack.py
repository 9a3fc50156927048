"""The coupled 3D racetrack case (issue 20, case (b)) on the 3D geometry path (orchestrator/run/participants3d.py,
the case file cases/emf_racetrack_groove): a racetrack coil, a sheet and a conducting, deformable die in the
staggered loop, on a coarse mesh (sizes x 2), built in Python (tests/coupling/racetrack_coarse.py).

References: (1) the conservation ledger per body (Σ nodal forces of the body vs Σ f V over its own
tetrahedra) is exact by construction: round-off; the two bodies' nodal forces add up to the loop's
resultant; (2) the fixed-mesh 3D EM solve of the same model, mesh and steps (one getdp process,
``solve_transient3d`` with BDF2): in 3 µs the sheet moves ~1e-7 m against a 1 mm gap, so GetDP's
per-conductor force integrals in the coupled run must equal it to far better than 1e-3, for the
sheet and for the die; (3) Newton: until a support reacts (the clamp is ~3 µs of wave travel away
from the loaded zone), the sheet's momentum Σ m v equals the impulse of the held forces on its free
nodes (less the half step of the first force: the explicit scheme's first velocity update is a half
step). Not for the die: its fixed top is one or two elements (8 mm here) above its loaded lower face,
so the support reacts from the first step (its momentum is printed, 10 % off its free impulse).
"""
import json

import numpy as np
import pytest

from pulseform.orchestrator.coupling.loop import StaggeredLoop
from pulseform.orchestrator.em.participant3d import ConductorBody3D, GetDPLoad3D
from pulseform.orchestrator.mech.participants import DolfinxMechanics
from pulseform.solvers.getdp.solver3d import solve_transient3d

from .racetrack_coarse import CASE, COARSE_SIZES, StepRecorder, coarse_participants
from warm_cli import pulseform_cli



def test_two_bodies_must_not_share_a_region_or_a_name(tmp_path):
    rm_like = type("M", (), {"q_ref": np.ones(1)})()
    sub = type("S", (), {})()
    a = ConductorBody3D("sheet", 201, sub, np.array([0, 1, 2]))
    b = ConductorBody3D("die", 201, sub, np.array([3, 4]))
    with pytest.raises(ValueError, match="own name and conductor region"):
        GetDPLoad3D(None, None, tmp_path, [a, b], rm_like)
    c = ConductorBody3D("die", 202, sub, np.array([2, 4]))
    with pytest.raises(ValueError, match="share EM nodes"):
        GetDPLoad3D(None, None, tmp_path, [a, c], rm_like)


# slow (the same coarse racetrack run, 3 us, and the same references (1)-(3) through the CLI in the default tier:
# tests/coupling/test_case_racetrack.py::test_racetrack_case_runs_through_the_driver; the loop's 3D transfer,
# ledgers and Newton without getdp: tests/coupling/test_loop_fake3d.py)
@pytest.mark.slow
@pytest.mark.getdp
def test_a_few_coupled_em_steps_with_sheet_and_die(tmp_path):
    case, solver, load, options, geo = coarse_participants(tmp_path)
    mech = DolfinxMechanics(solver)
    loop = StaggeredLoop(load, mech, options)
    rec = StepRecorder(case, solver, load)
    loop.run_until(3e-6, on_em_step=rec)
    load.close()
    rows, m, n = rec.rows, len(rec.rows), options.n
    ref = solve_transient3d(load.model, geo.mesh, 3e-6, m, tmp_path / "fixed", time_scheme="bdf2",
                            element_output="none")
    errs = {}
    for k, name in enumerate(("sheet", "die")):
        got = np.array([r[f"{name}_getdp_force_z_N"] for r in rows])
        f_ref = ref.conductor_force[:, k, 2]
        errs[name] = np.abs(got - f_ref).max() / np.abs(f_ref).max()
    total = np.array([r["force_z_N"] for r in rows])
    parts = np.array([r["sheet_force_z_N"] + r["die_force_z_N"] for r in rows])
    ledgers = {k: max(r[k] for r in rows) for k in ("conservation_error_rel", "sheet_ledger_rel", "die_ledger_rel")}
    mom_sheet = max(abs(r["sheet_momentum_z_kg_m_s"] / r["sheet_free_impulse_z_Ns"] - 1) for r in rows)
    mom_die = abs(rows[0]["die_momentum_z_kg_m_s"] / rows[0]["die_free_impulse_z_Ns"] - 1)
    uz = max(r["sheet_max_uz_m"] for r in rows)
    print(f"\n{geo.mesh.n_tets} EM tets (sheet {len(solver.bodies['sheet'].cells)}, die "
          f"{len(solver.bodies['die'].cells)}), {m} EM steps of {n} mechanical steps: GetDP force vs fixed-mesh "
          f"solve sheet {errs['sheet']:.1e}, die {errs['die']:.1e}; ledgers {ledgers}; momentum vs free impulse: "
          f"sheet {mom_sheet:.1e}, die (1st step) {mom_die:.1e}; max u_z {uz:.2e} m; die/sheet force "
          f"{rows[-1]['die_force_z_N'] / rows[-1]['sheet_force_z_N']:.2e}")
    assert m == 3 and np.abs(ref.conductor_force[:, :, 2]).min(axis=0).min() > 0
    assert max(ledgers.values()) < 1e-12
    np.testing.assert_allclose(parts, total, rtol=1e-12)
    assert errs["sheet"] < 1e-3 and errs["die"] < 1e-3
    assert mom_sheet < 1e-3


@pytest.mark.slow
@pytest.mark.getdp
def test_coarse_racetrack_end_to_end(tmp_path):
    """The whole run (60 µs: the current's first half wave) on the coarse mesh (sizes x 2) through ``pulseform
    run``, with four field outputs: ledgers at round-off over every step (exact by construction), the energy
    ledger of the mechanics (external work = kinetic + elastic + plastic + contact + viscous, to its
    time-discretisation error), the sheet formed upwards into the groove (not below its start: its lowest node at
    the output times, from the field files), the EM mesh frozen (a failed remesh) only after the force's main pulse
    with little of the impulse after it, and the section pictures drawn. The figures of the default mesh are in
    studies/emf_racetrack_groove/reference/ and docs/coupling.md."""
    from pulseform.orchestrator.run.mech_fields import read_fields
    from pulseform.orchestrator.run.pictures_section3d import draw_sections3d

    out = tmp_path / "run"
    r = pulseform_cli(["run", str(CASE), "--out", str(out), "--quiet", "--set", "output.plots=false",
                       "--set", "output.field_interval=15e-6", *(a for s in COARSE_SIZES for a in ("--set", s))])
    assert r.returncode == 0, r.stderr[-3000:]
    m = json.loads((out / "metrics.json").read_text())
    print("\n" + ", ".join(f"{k} {v:.4g}" for k, v in m.items() if isinstance(v, float)))
    assert m["status"] == "ok" and m["end_time_s"] == pytest.approx(60e-6, rel=1e-9)
    assert max(m["conservation_error_rel"], m["sheet_ledger_rel"], m["die_ledger_rel"]) < 1e-12
    assert abs(m["energy_error_rel"]) < 0.02
    sheet = read_fields(out)["sheet"]
    min_uz = min(float(sheet.read(k, ("displacement_m",))["displacement_m"][:, 2].min()) for k in range(len(sheet.times)))
    assert m["sheet_max_uz_mm"] > 0.5 and 1e3 * min_uz > -0.1
    if m.get("em_mesh_frozen_at_s") is not None:
        assert m["em_mesh_frozen_at_s"] > 45e-6
        assert abs(m["impulse_after_freeze_device_z_Ns"]) < 0.1 * abs(m["force_impulse_z_Ns"])
    paths = draw_sections3d(out)
    assert len(paths) == 4 and all(p.stat().st_size > 10_000 for p in paths)


def _freezing_load(freeze: bool, breaks_at: int):
    """A FreezingGetDPLoad3D around a fake mover (no getdp): the mesh follows the bodies until the
    ``breaks_at``-th call, then the mover raises MeshQualityError as the real one does."""
    from pulseform.orchestrator.em.frozen3d import FreezingGetDPLoad3D
    from pulseform.orchestrator.mesh.motion import MeshQualityError

    class Mover:
        calls, last_min_quality = 0, 0.5

        def moved(self, u):
            Mover.calls += 1
            if Mover.calls >= breaks_at:
                raise MeshQualityError("tetrahedron 7 inverted")
            return points + u

    points = np.zeros((4, 3))
    load = FreezingGetDPLoad3D.__new__(FreezingGetDPLoad3D)
    load.mesh = type("M", (), {"points": points})()
    load.bodies = [ConductorBody3D("sheet", 201, None, np.arange(4))]
    load.mover, load.min_quality, load._moved = Mover(), 1.0, None
    load.timers, load.impulse_device = {"mesh_motion_s": 0.0}, 0.0   # a freeze records the impulse until it
    load.freeze, load.frozen_at, load.freeze_reason, load._last_valid = freeze, None, "", points.copy()
    return load


def test_the_em_mesh_freezes_at_the_last_valid_one_or_stops():
    from pulseform.orchestrator.mesh.motion import MeshQualityError

    mech = type("Mech", (), {"positions": lambda self: {"sheet": np.full((4, 3), self.u)}})
    load = _freezing_load(True, breaks_at=3)
    for k, u in enumerate((1e-4, 2e-4, 3e-4, 4e-4)):
        m = mech()
        m.u = u
        load.follow(float(k), m)
    # steps 0 and 1 followed; the third call broke: steps 2 and 3 keep step 1's mesh
    assert load.frozen_at == 2.0 and "inverted" in load.freeze_reason
    np.testing.assert_array_equal(load._moved[1], np.full((4, 3), 2e-4))
    assert load._moved[0] == 3.0
    stop = _freezing_load(False, breaks_at=1)
    m = mech()
    m.u = 1e-4
    with pytest.raises(MeshQualityError):
        stop.follow(0.0, m)


@pytest.mark.getdp
def test_order2_em_in_the_coupled_loop_freezes_instead_of_remeshing(tmp_path):
    """Second-order edge elements (``geometry.em_order = 2``): the remeshing load refuses them (its state carry
    maps Whitney edge unknowns only; the case file refuses the pair too: tests/coupling/test_case_racetrack.py);
    with ``on_mesh_break = "freeze"`` the coupled loop runs them (the persistent getdp gets the order from the
    model) and its sheet and die forces equal a fixed-mesh order-2 solve with the same steps (the mesh barely
    moves in 2 us: bar 1e-3, as above), with the ledgers closed."""
    from pulseform.orchestrator.em.remesh3d import RemeshingGetDPLoad3D

    case, solver, load, options, geo = coarse_participants(tmp_path, "geometry.em_order=2",
                                                           'geometry.on_mesh_break="freeze"')
    assert load.model.order == 2 and not load.model.order2_air
    assert not isinstance(load, RemeshingGetDPLoad3D)
    with pytest.raises(ValueError, match="remesh with order 2"):
        RemeshingGetDPLoad3D(geo.mesh, load.model, tmp_path / "refused", load.bodies, load.mover,
                             make_mover=lambda m: None, planes=[(p.point, p.normal) for p in geo.planes])
    mech = DolfinxMechanics(solver)
    loop = StaggeredLoop(load, mech, options)
    rec = StepRecorder(case, solver, load)
    loop.run_until(2e-6, on_em_step=rec)
    load.close()
    rows, m = rec.rows, len(rec.rows)
    ref = solve_transient3d(load.model, geo.mesh, 2e-6, m, tmp_path / "fixed", time_scheme="bdf2",
                            element_output="none")
    for k, name in enumerate(("sheet", "die")):
        got = np.array([r[f"{name}_getdp_force_z_N"] for r in rows])
        err = np.abs(got - ref.conductor_force[:, k, 2]).max() / np.abs(ref.conductor_force[:, k, 2]).max()
        print(f"\norder 2 coupled, {ref.n_dofs} dofs: {name} force vs fixed-mesh solve {err:.1e}")
        assert err < 1e-3
    assert m == 2 and max(r["conservation_error_rel"] for r in rows) < 1e-12
