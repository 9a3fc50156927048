"""Carrying the EM state across steps (the staggered coupling's path).

Reference: a continuous run of the same sub-steps in one getdp process (same mesh, same dt).
Both the restart path (-restart -res) and the general path (Init constraint fed with the nodal
r a_phi interpolated in material coordinates) must reproduce it to round-off on a fixed mesh,
for prescribed currents and for the capacitor circuit.
"""
import json

import numpy as np
import pytest

from pulseform.solvers.getdp import (Circuit, Coil, Conductor, DampedSine, EMModel, EMState, GetDPSolver, Rect,
                                     coil_conductor_mesh, em_metrics)

from getdp_testlib import needs_getdp

TURNS = [Rect(0.010 + i * 0.004, -0.003, 0.013 + i * 0.004, -0.001) for i in range(5)]
DISK = Rect(0.0, 0.0, 0.06, 0.001)


def mesh_and_models(h_conductor=5e-4):
    mesh = coil_conductor_mesh([TURNS], [DISK], r_domain=0.15, r_shell=0.1875, h_fine=1.5e-3, h_coarse=2.5e-2,
                               h_conductor=h_conductor)
    prescribed = EMModel(True, coils=[Coil(5, waveform=DampedSine(20e3, 1e4, 1e5))],
                         conductors=[Conductor(3.5e7)], shell=(0.15, 0.1875))
    circuit = EMModel(True, coils=[Coil(5)], conductors=[Conductor(3.5e7)],
                      circuit=Circuit(C=50e-6, V0=5e3, R_ext=1e-3, L_ext=1e-6), shell=(0.15, 0.1875))
    return mesh, prescribed, circuit


@pytest.mark.getdp
@needs_getdp
@pytest.mark.parametrize("kind", ["prescribed", "circuit"])
def test_restart_and_init_paths_reproduce_continuous_run(work, kind):
    mesh, prescribed, circuit = mesh_and_models()
    model = prescribed if kind == "prescribed" else circuit
    solver = GetDPSolver(model, work)
    s0 = solver.initial_state()
    ref, _ = solver.step(mesh, s0, 6e-6, 6, run_name="continuous")
    results = {"restart": [], "init": []}
    for path in results:
        state = s0
        for k in range(3):
            state = EMState.from_dict(json.loads(json.dumps(state.to_dict())))   # checkpoint round trip
            res, state = solver.step(mesh.with_points(mesh.points.copy()), state, (k + 1) * 2e-6, 2,
                                     run_name=f"{path}_{k}", force_init_path=(path == "init" and k > 0))
            results[path].append(res)
        if path == "restart":
            assert "-restart" in results[path][-1].run.argv
            assert "-cal" in results[path][-1].run.argv      # pre-processing reused
        else:
            assert "-restart" not in results[path][-1].run.argv
        f = np.concatenate([r.force_density for r in results[path]])
        i = np.concatenate([r.coil_current for r in results[path]])
        err_f = np.abs(f - ref.force_density).max() / np.abs(ref.force_density).max()
        err_i = np.abs(i - ref.coil_current).max() / np.abs(ref.coil_current).max()
        print(f"\n{kind}/{path}: max rel. deviation from the continuous run: force density {err_f:.1e},"
              f" current {err_i:.1e}")
        assert err_f < 1e-9 and err_i < 1e-9
        assert np.allclose(results[path][-1].coil_heat, ref.coil_heat, rtol=1e-9)
        if kind == "circuit":
            vc = np.concatenate([r.capacitor_voltage for r in results[path]])
            assert np.abs(vc - ref.capacitor_voltage).max() < 1e-9 * 5e3
    m_split, m_ref = em_metrics(results["restart"]), em_metrics([ref])
    for key, val in m_ref.items():
        assert m_split[key] == pytest.approx(val, rel=1e-9)


@pytest.mark.getdp
@needs_getdp
def test_new_mesh_through_init_constraint(work):
    """Remeshed (different connectivity, similar size): the interpolated state continues the run.

    Reference: a continuous run on the new mesh.  The remaining difference is the history having
    been computed on the other mesh (its discretization error enters through j = -sigma dA/dt).
    """
    mesh, model, _ = mesh_and_models()
    other = coil_conductor_mesh([TURNS], [DISK], r_domain=0.15, r_shell=0.1875, h_fine=1.5e-3, h_coarse=2.5e-2,
                                h_conductor=4.9e-4)
    assert not mesh.same_connectivity(other)
    solver = GetDPSolver(model, work)
    ref, _ = solver.step(other, solver.initial_state(), 5e-6, 5, run_name="reference_on_new_mesh")
    _, st1 = solver.step(mesh, solver.initial_state(), 4e-6, 4, run_name="old_mesh")
    res, st2 = solver.step(other, st1, 5e-6, 1, run_name="new_mesh")
    assert "-restart" not in res.run.argv
    f_ref, f_new = ref.conductor_force[-1, 0, 1], res.conductor_force[-1, 0, 1]
    print(f"\nF_z at 5 us on the new mesh: continuous {f_ref:.2f} N, continued from the old mesh {f_new:.2f} N "
          f"({f_new / f_ref - 1:+.2%})")
    assert abs(f_new / f_ref - 1) < 0.02
    # and the next step on the same new mesh takes the restart path again
    res3, _ = solver.step(other, st2, 6e-6, 1, run_name="new_mesh_next")
    assert "-restart" in res3.run.argv


@pytest.mark.getdp
@needs_getdp
def test_moved_nodes_material_coordinates(work):
    """Disk lifted by 50 um (same connectivity): restart path == Init path with material points.

    With the state carried in material coordinates the two paths carry identical nodal values,
    so they agree to round-off; carrying values at fixed spatial positions instead differs.
    """
    mesh, model, _ = mesh_and_models()
    p = mesh.points
    rho = np.hypot(p[:, 0], p[:, 1])
    lift = 5e-5 * np.clip((p[:, 1] + 0.0009) / 0.0009, 0, 1) * np.clip((0.14 - rho) / 0.04, 0, 1)
    moved = mesh.with_points(np.column_stack([p[:, 0], p[:, 1] + lift]))
    assert np.all(moved.areas() > 0)
    solver = GetDPSolver(model, work)
    _, st1 = solver.step(mesh, solver.initial_state(), 4e-6, 4, run_name="before")
    a, _ = solver.step(moved, st1, 5e-6, 1, run_name="restart")
    b, _ = solver.step(moved, st1, 5e-6, 1, run_name="init", material_points=mesh.points, force_init_path=True)
    c, _ = solver.step(moved, st1, 5e-6, 1, run_name="spatial", force_init_path=True)
    assert "-restart" in a.run.argv and "-cal" in a.run.argv and "-restart" not in b.run.argv
    fa, fb, fc = (r.conductor_force[-1, 0, 1] for r in (a, b, c))
    print(f"\nF_z after lifting the disk 50 um: restart {fa:.3f} N, Init (material) {fb:.3f} N, "
          f"Init (spatial) {fc:.3f} N")
    assert abs(fb / fa - 1) < 1e-9
    assert abs(fc / fa - 1) > 1e-4


@pytest.mark.getdp
@needs_getdp
def test_keep_runs_prunes_old_folders(work):
    import time
    mesh, model, _ = mesh_and_models()
    solver = GetDPSolver(model, work, keep_runs=2)
    state = solver.initial_state()
    for k in range(4):
        res, state = solver.step(mesh, state, (k + 1) * 1e-6, 1)
    deadline = time.time() + 10
    while time.time() < deadline and len(list(work.iterdir())) > 2:
        time.sleep(0.05)
    assert sorted(p.name for p in work.iterdir()) == ["step_00002", "step_00003"]
    assert "-restart" in res.run.argv
