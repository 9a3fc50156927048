"""A B–H curve on the persistent getdp (issue 35): Newton's iterations inside its loop
(``decks/Lib_PersistentStep.pro`` calls ``PF_SolveStep`` of ``decks/Lib_Newton.pro``) against the per-step path
(one getdp process per EM step, the independent reference: its BDF2 state through text tables and Init constraints).

Both start Newton from the same iterate (the BDF2 start state x~: GetDP's Generate at a new time step copies the
last solution) and take the same iterations, each a fresh factorisation of the same Jacobian, so they agree to
round-off -- not only to Newton's tolerance -- with the same iteration counts: bound 1e-12 relative (measured
1.2e-13 in 2D, 7.7e-15 in 3D). The disk is a conducting steel (the soft steel's curve of
tests/getdp/test_magnetic.py) under the demo's coil on its bank, driven into the curve's knee.
"""
from __future__ import annotations

import numpy as np
import pytest

from pulseform.solvers.getdp import Circuit, Coil, Conductor, EMModel, GetDPSolver
from pulseform.solvers.getdp.bh_curve import BHCurve, NewtonFailed
from pulseform.solvers.getdp.persistent import PersistentGetDPSolver
from pulseform.solvers.getdp.persistent_process import FactorReuse

from getdp_testlib import needs_getdp
from test_persistent import TIMES, Bulge, _mesh

pytestmark = [pytest.mark.getdp, needs_getdp]

#: a soft steel's shape (A/m, T), as tests/getdp/test_magnetic.py
STEEL = BHCurve(h=(0, 100, 200, 400, 1000, 3000, 10000, 1e5), b=(0, 0.8, 1.1, 1.3, 1.45, 1.6, 1.75, 2.1))
BANK = Circuit(C=50e-6, V0=6e3, R_ext=0.01, L_ext=2e-6)


def _model(curve=STEEL, tol=1e-10, max_it=30) -> EMModel:
    return EMModel(True, coils=[Coil(5)], conductors=[Conductor(4e6, bh_curve=curve)], circuit=BANK,
                   shell=(0.15, 0.1875), newton_tolerance=tol, newton_max_iterations=max_it)


def _march(solver, meshes, times, redo_at=None):
    """Step ``solver`` through ``times`` on ``meshes(t)``; per step (current, capacitor voltage, energy, coil heat,
    conductor force, the trapezoid force densities) and Newton's linear solves; ``redo_at``: that step first on
    another geometry, then again (coupling.iterate)."""
    state, rows, counts = solver.initial_state(), [], []
    material = meshes(0.0).points   # the material coordinates: the mesh at rest
    for k, t in enumerate(times):
        if k == redo_at:
            solver.step(meshes(0.5 * t), state, t, material_points=material)
        r, state = solver.step(meshes(t), state, t, material_points=material)
        rows.append(np.concatenate([[r.coil_current[-1, 0], r.capacitor_voltage[-1], r.magnetic_energy[-1],
                                     r.coil_heat[0], r.conductor_force[-1, 0, 1]], r.force_density_mean.ravel()]))
        counts += r.newton_iterations or []   # None for a linear model
    if hasattr(solver, "close"):
        solver.close()
    return np.array(rows), counts, state


def _rel(a, b) -> float:
    """Largest difference over the run relative to each column's largest magnitude (the force densities: to the
    largest of any element)."""
    d = np.abs(a - b)
    scalars = (d[:, :5].max(axis=0) / np.abs(a[:, :5]).max(axis=0)).max()
    return float(max(scalars, d[:, 5:].max() / np.abs(a[:, 5:]).max()))


def test_bh_curve_on_the_persistent_getdp_equals_the_per_step_path(work):
    """Moving mesh, variable steps, circuit, a redo: the persistent getdp with a B–H curve equals the per-step path
    to 1e-12 (every output; Newton's counts equal, some step above one solve: the curve is active, and the run
    differs from the same disk in vacuum by more than 1 %). Kept factors asked for are not used: every Newton
    solve is a factorisation (the state's count), no GCR correction."""
    mesh = _mesh()
    bulge = Bulge(mesh)
    ref, n_ref, _ = _march(GetDPSolver(_model(), work / "per_step", time_scheme="bdf2"), bulge, TIMES)
    got, n_got, state = _march(PersistentGetDPSolver(_model(), work / "persistent", factor_reuse=FactorReuse(1e-10)),
                               bulge, TIMES, redo_at=5)
    vac, _, _ = _march(PersistentGetDPSolver(_model(curve=None), work / "vacuum"), bulge, TIMES)
    print(f"\nB-H curve, persistent vs per-step: max rel diff {_rel(ref, got):.2g}; Newton's solves {n_got}; "
          f"vs vacuum {_rel(ref, vac):.2g}")
    assert _rel(ref, got) < 1e-12
    assert n_got == n_ref and max(n_got) > 1 and len(n_got) == len(TIMES)
    assert _rel(ref, vac) > 0.01
    assert state.factorisations == sum(n_got) and state.corrections == 0


def test_newton_above_its_tolerance_on_the_persistent_getdp_is_one_line(work):
    """One Newton iteration allowed at a tolerance of 1e-14: the first step that needs more stops the run with
    NewtonFailed, whose one-line message names the keys (as the per-step path's)."""
    mesh = _mesh()
    solver = PersistentGetDPSolver(_model(tol=1e-14, max_it=1), work / "fails")
    state = solver.initial_state()
    with pytest.raises(NewtonFailed) as err:
        for t in TIMES:
            _, state = solver.step(mesh, state, t)
    solver.close()
    msg = str(err.value).splitlines()[0]
    assert "em.newton_tolerance = 1e-14" in msg and "em.newton_max_iterations = 1" in msg, msg


@pytest.mark.slow
def test_bh_curve_on_the_persistent_3d_getdp_equals_the_per_step_path(work):
    """3D (the coarse 10° sector of tests/getdp/test_persistent3d.py, the disk bulging and sliding): the
    persistent getdp with a B–H curve equals the per-step :class:`EM3DStepper` to 1e-12 (F_z, current, capacitor
    voltage, energy, every element's force density; measured 7.7e-15), Newton's counts equal and above one solve
    somewhere."""
    from dataclasses import replace

    from pulseform.solvers.getdp.persistent3d import PersistentEM3DStepper
    from pulseform.solvers.getdp.stepper3d import EM3DStepper

    import test_persistent3d as p3

    mesh = p3._mesh(work / "disk.msh")
    model = replace(p3._model(), conductors=[Conductor(4e6, bh_curve=STEEL)], newton_tolerance=1e-10)
    counts = {}

    def march(stepper, name):
        (work / name).mkdir()
        bulge = p3.Bulge(mesh, work / name)
        rows, state = [], stepper.initial_state()
        counts[name] = []
        for k, t in enumerate(p3.TIMES):
            r, state = stepper.step(bulge(k, t), state, float(t))
            counts[name] += r.newton_iterations
            rows.append(np.concatenate([[r.conductor_force[-1, 0, 2], r.coil_current[-1, 0], r.capacitor_voltage[-1],
                                         r.magnetic_energy[-1]], r.force_density[-1].ravel(),
                                        r.force_density_mean.ravel()]))
        if hasattr(stepper, "close"):
            stepper.close()
        return np.array(rows)

    ref = march(EM3DStepper(model, work / "per_step", time_scheme="bdf2"), "m_ref")
    got = march(PersistentEM3DStepper(model, work / "persistent", factor_reuse=FactorReuse(1e-10)), "m_got")
    print(f"\n3D B-H curve, persistent vs per-step: max rel diff {p3._rel(ref, got):.2g}; Newton's solves {counts}")
    assert p3._rel(ref, got) < 1e-12
    assert counts["m_got"] == counts["m_ref"] and max(counts["m_got"]) > 1
