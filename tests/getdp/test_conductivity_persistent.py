"""A conductivity that follows temperature on the persistent getdp (issue 33, item 3): the step messages carry σ
per element (``decks/Lib_Persistent.pro``, ``PF_SigmaElem``), against the per-step path (one getdp process per EM
step, σ per element through the ``InterpolationLinear[ElementNum[]]`` list of ``run.pro``: the independent
reference, tests/getdp/test_conductivity.py checks it against constant conductivities).

Both run the same BDF2 scheme on the same moved meshes with the same σ per element every step (the disk's
temperatures change every step, hotter outwards; the coil's σ follows its own Joule heat), so they must agree to
round-off, as the persistent getdp does without σ(T) (tests/getdp/test_persistent.py: 1e-12). Kept LU factors
(``em.factor_reuse_tol``) meet a matrix whose σ changed every step: GCR solves each step's own assembled system,
so the results stay those of a factorisation per step to the tolerance's order; a resume that replays the
checkpoint's log (the σ of each message logged with it) repeats the run bit for bit.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from pulseform.solvers.getdp import Circuit, Coil, Conductor, EMModel, EMState, GetDPSolver, Rect, coil_conductor_mesh
from pulseform.solvers.getdp.conductivity import ConductivityTable, LinearResistivity
from pulseform.solvers.getdp.mesh import conductor_tag
from pulseform.solvers.getdp.persistent import PersistentGetDPSolver
from pulseform.solvers.getdp.persistent_process import FactorReuse

from getdp_testlib import needs_getdp
from test_persistent import Bulge   # the bulging disk, the air following harmonically

pytestmark = [pytest.mark.getdp, needs_getdp]

TURNS = [Rect(0.010 + i * 0.004, -0.003, 0.013 + i * 0.004, -0.001) for i in range(5)]
DISK = Rect(0.0, 0.0, 0.06, 0.001)
#: the demo's bank and a 5-turn coil under an aluminium disk; the coil's σ from a table, its heat capacity small so
#: that its σ falls by ~3 % over the steps; the disk's resistivity linear in T (α = 4e-3 /K)
COIL_LAW = ConductivityTable((250.0, 800.0), (6.5e7, 2.0e7))
DISK_LAW = LinearResistivity(2.5e7, 4.0e-3, 293.15)
MODEL = EMModel(True, coils=[Coil(5, conductivity_law=COIL_LAW, initial_temperature=293.15, heat_capacity=2.0)],
                conductors=[Conductor(2.5e7, conductivity_law=DISK_LAW)],
                circuit=Circuit(C=50e-6, V0=6e3, R_ext=0.01, L_ext=2e-6), shell=(0.15, 0.1875))
#: variable steps (ratios 0.37 and 3.8, as when the coupling lands on milestones)
TIMES = np.cumsum(np.where(np.arange(10) % 5 == 3, 0.37e-6, np.where(np.arange(10) % 5 == 4, 1.4e-6, 0.5e-6)))


def _mesh():
    return coil_conductor_mesh([TURNS], [DISK], r_domain=0.15, r_shell=0.1875, h_fine=2e-3, h_coarse=3e-2,
                               h_conductor=1e-3)


def _temperatures(mesh, k):
    """The disk's element rows and their temperatures at step k (K): 293 K at the axis, up to +400 K at the rim
    by the last step."""
    rows = np.flatnonzero(mesh.tri_tags == conductor_tag(1))
    r = mesh.points[mesh.triangles[rows]].mean(axis=1)[:, 0]
    return rows, 293.15 + 400.0 * (r / 0.06) * (k + 1) / len(TIMES)


def _march(solver, mesh, bulge, restart_at=None, fields_at=None):
    """Step ``solver`` through TIMES on the bulging disk with the disk's temperatures of :func:`_temperatures`;
    per step (coil current, capacitor voltage, coil heat, disk Joule power, disk force, force density, Joule
    density per element). ``restart_at``: a checkpoint there, then a new solver replaying its log (a resume)."""
    state, out = solver.initial_state(), []
    for k, t in enumerate(TIMES):
        if k == restart_at:
            full = solver.checkpoint_state(state)
            state = EMState.from_dict(json.loads(json.dumps(full.to_dict())))
            log = {key: v.copy() for key, v in solver.replay_arrays().items()}
            solver.close()
            solver = PersistentGetDPSolver(MODEL, solver.work_dir.parent / (solver.work_dir.name + "_b"),
                                           factor_reuse=solver.factor_reuse)
            solver.load_replay(log)
        solver.set_element_temperatures(*_temperatures(mesh, k))
        r, state = solver.step(bulge(t), state, t, material_points=mesh.points, field_output=k == fields_at)
        out.append(np.concatenate([[r.coil_current[-1, 0], r.capacitor_voltage[-1], r.coil_heat[0],
                                    r.conductor_power[-1, 0], r.conductor_force[-1, 0, 1]],
                                   r.force_density[-1].ravel(), r.joule_density[-1].ravel()]))
    if hasattr(solver, "close"):
        solver.close()
    return out, state


def _rel(a, b):
    return max(np.abs(x - y).max() / np.abs(x).max() for x, y in zip(a, b))


def test_persistent_getdp_with_conductivity_per_element_equals_the_per_step_path(work):
    """Every output (current, capacitor voltage, coil heat, the disk's Joule power and force, force and Joule
    density per element) equal to the per-step path to 1e-12 at every step (measured 2.6e-13); the coil's σ
    of the last step the same number; and the conductivities matter: the same run at the constant σ(T0)
    differs by more than 1 %."""
    mesh = _mesh()
    bulge = Bulge(mesh)
    ref, s_ref = _march(GetDPSolver(MODEL, work / "per_step", time_scheme="bdf2"), mesh, bulge, fields_at=4)
    got, s_got = _march(PersistentGetDPSolver(MODEL, work / "persistent"), mesh, bulge, fields_at=4)
    print(f"\nσ(T): persistent vs per-step, max rel diff {_rel(ref, got):.2g} over {len(TIMES)} steps; coil σ "
          f"{s_got.coil_sigma[0]:.6g} S/m")
    assert _rel(ref, got) < 1e-12
    assert s_got.coil_sigma[0] == pytest.approx(s_ref.coil_sigma[0], rel=1e-13)
    assert s_got.coil_sigma[0] < 0.99 * float(COIL_LAW(293.15))   # the coil heated: its σ fell
    constant = EMModel(True, coils=[Coil(5, sigma=float(COIL_LAW(293.15)))], conductors=[Conductor(2.5e7)],
                       circuit=MODEL.circuit, shell=MODEL.shell)
    plain, _ = _march(PersistentGetDPSolver(constant, work / "constant"), mesh, bulge)
    assert _rel(plain, got) > 1e-2


def test_kept_factors_and_a_resume_with_conductivity_per_element(work):
    """Kept LU factors (tol 1e-10) while σ changes every step: GCR solves each step's own system (assembled with
    its σ) to a relative residual of 1e-10, so its distance to a factorisation per step is the solve's error
    (condition number × 1e-10), not the σ change's: within 3× of the same distance for the constant-σ disk and coil
    on the same steps and meshes (measured 3.0e-8 vs 1.9e-8: these variable steps need more corrections than
    test_persistent.py's equal ones), with one factorisation for all the steps. A resume from a checkpoint at
    step 6 that replays the log (each message's σ logged) repeats the kept-factor run bit for bit."""
    mesh = _mesh()
    bulge = Bulge(mesh)
    keep = FactorReuse(tol=1e-10)
    constant = EMModel(True, coils=[Coil(5, sigma=float(COIL_LAW(293.15)))], conductors=[Conductor(2.5e7)],
                       circuit=MODEL.circuit, shell=MODEL.shell)
    fresh, _ = _march(PersistentGetDPSolver(MODEL, work / "fresh"), mesh, bulge)
    kept, state = _march(PersistentGetDPSolver(MODEL, work / "kept", factor_reuse=keep), mesh, bulge)
    fresh_c, _ = _march(PersistentGetDPSolver(constant, work / "fresh_c"), mesh, bulge)
    kept_c, state_c = _march(PersistentGetDPSolver(constant, work / "kept_c", factor_reuse=keep), mesh, bulge)
    resumed, _ = _march(PersistentGetDPSolver(MODEL, work / "resumed", factor_reuse=keep), mesh, bulge, restart_at=6)
    print(f"\nkept factors vs a factorisation per step: σ(T) {_rel(fresh, kept):.1e} ({state.factorisations} "
          f"factorisations, {state.corrections} corrections in {len(TIMES)} steps); constant σ "
          f"{_rel(fresh_c, kept_c):.1e} ({state_c.factorisations}, {state_c.corrections})")
    assert state.factorisations == 1 and state.corrections > 0
    assert 0 < _rel(fresh, kept) < 3.0 * _rel(fresh_c, kept_c)
    assert all(np.array_equal(a, b) for a, b in zip(resumed, kept))
