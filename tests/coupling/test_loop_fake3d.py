"""The 3D staggered loop with a fake EM participant (orchestrator/coupling/fakes.py, ``AnalyticLorentz3D``): the
coarse racetrack case's meshes, bodies (sheet and die, DOLFINx explicit) and air mover (tests/coupling/
racetrack_coarse.py), the GetDP load replaced by an analytic Lorentz force density on the bodies' tetrahedra of
the moving EM mesh -- the loop's 3D mechanics (mesh motion, force transfer, ledgers, checkpoint and resume) in
seconds, without getdp. The same checks with GetDP's forces: tests/coupling/test_coupled_racetrack.py and,
through the CLI, tests/coupling/test_case_racetrack.py (slow: its SIGINT/resume) and
tests/coupling/test_case_racetrack_remesh.py.

References: (1) the ledger per body (Σ nodal forces vs Σ f V) is exact by construction: round-off; (2) Newton:
until the clamp reacts (a density localised at the centre, ~3 µs of wave travel from the clamp), the sheet's
momentum equals the impulse of the held forces on its free nodes (less the half step of the first force); (3) the
EM mesh follows the bodies: its nodes of each body are the body's positions (u added to X, round-off) and the
moved air stays valid; (4) a checkpoint (the loop's counters, the mechanics, the load, through the run's npz
writer) and a resume into fresh participants equal the uninterrupted run bitwise.
"""
import math
from pathlib import Path

import numpy as np
import pytest

from pulseform.orchestrator.coupling.fakes import AnalyticLorentz3D
from pulseform.orchestrator.coupling.loop import StaggeredLoop
from pulseform.orchestrator.mech.participants import DolfinxMechanics
from pulseform.orchestrator.run.checkpoint import load_checkpoint, save_checkpoint

from .racetrack_coarse import StepRecorder, coarse_participants

#: the density: F0 sin²(π t / T) e^{-(x² + y²) / R²} along +z (a pulse rising over T, localised at the centre)
F0, T, R = 1e10, 10e-6, 10e-3
T_END, T_CUT = 3e-6, 1e-6


def density(c: np.ndarray, t: float) -> np.ndarray:
    f = np.zeros_like(c)
    f[:, 2] = F0 * math.sin(math.pi * t / T) ** 2 * np.exp(-(c[:, 0] ** 2 + c[:, 1] ** 2) / R ** 2)
    return f


def _loop(work: Path):
    """(case, solver, fake load, loop) of fresh participants (the coarse racetrack meshed in ``work``)."""
    case, solver, load, options, geo = coarse_participants(work)
    load.close()   # the GetDP load is built and not used: its mesh, bodies and air mover are
    fake = AnalyticLorentz3D(load.mesh, load.bodies, load.mover, density)
    return case, solver, fake, StaggeredLoop(fake, DolfinxMechanics(solver), options)


def _state(solver) -> dict[str, np.ndarray]:
    return {f"{n}/{k}": np.array(getattr(b, k)) for n, b in solver.bodies.items() for k in ("x", "v")}


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    """The run to T_END, its checkpoint written at T_CUT (the loop stops at a milestone and goes on, as the
    driver's does at an output time)."""
    work = tmp_path_factory.mktemp("fake3d")
    case, solver, fake, loop = _loop(work / "a")
    rec = StepRecorder(case, solver, fake)
    loop.run_until(T_CUT, on_em_step=rec)
    arrays = {**{f"mech/{k}": v for k, v in loop.mech.state_dict().items()},
              **{f"load/{k}": v for k, v in fake.state_dict().items()},
              **{f"loop/{k}": v for k, v in loop.counters.state_dict().items()}}
    save_checkpoint(work / "checkpoint.npz", arrays, {"t": T_CUT})
    loop.run_until(T_END, on_em_step=rec)
    return case, solver, fake, loop, rec.rows, fake.x_em.copy(), work / "checkpoint.npz"


def test_fake_lorentz_ledgers_newton_and_the_moving_em_mesh(uninterrupted):
    case, solver, fake, loop, rows, _, _ = uninterrupted
    assert len(rows) == 3 and loop.mech.time == pytest.approx(T_END, rel=1e-12)
    # (1) the ledger at round-off; the bodies' nodal forces add up to the loop's resultant
    assert loop.counters.ledger_max < 1e-12 and max(r["conservation_error_rel"] for r in rows) < 1e-12
    total = np.array([r["force_z_N"] for r in rows])
    parts = np.array([sum(float(f[:, 2].sum()) for f in fake.last_forces.values())])
    np.testing.assert_allclose(parts, total[-1:], rtol=1e-12)
    assert np.all(total > 0)
    # (2) Newton on the sheet's free nodes
    mom = max(abs(r["sheet_momentum_z_kg_m_s"] / r["sheet_free_impulse_z_Ns"] - 1) for r in rows)
    uz = max(r["sheet_max_uz_m"] for r in rows)
    # (3) the EM mesh follows the bodies (moved at the start of each step: here the end's positions); the air
    # stays valid
    fake.follow(loop.mech.time, loop.mech)
    dev = max(float(np.abs(fake.x_em[b.body_to_em] - solver.bodies[b.name].x).max()) for b in fake.bodies)
    q = min(r["em_mesh_min_quality"] for r in rows)
    print(f"\nfake Lorentz load on the coarse racetrack, {len(rows)} EM steps: ledger {loop.counters.ledger_max:.1e}, "
          f"sheet momentum vs free impulse {mom:.1e}, max u_z {uz:.2e} m, EM nodes vs bodies {dev:.1e} m, "
          f"min air quality {q:.3f}")
    assert mom < 1e-3 and uz > 0
    assert dev < 1e-15 and q > 0


def test_checkpoint_then_resume_into_fresh_participants_is_bitwise(uninterrupted, tmp_path):
    _, solver_ref, _, loop_ref, rows_ref, x_em_ref, checkpoint = uninterrupted
    got, meta = load_checkpoint(checkpoint)
    assert meta == {"t": T_CUT}

    def part(prefix: str) -> dict[str, np.ndarray]:
        return {k[len(prefix):]: v for k, v in got.items() if k.startswith(prefix)}

    case, solver, fake2, loop2 = _loop(tmp_path / "c")
    loop2.mech.load_state_dict(part("mech/"))
    fake2.load_state_dict(part("load/"))
    loop2.counters.load_state_dict(part("loop/"))
    rec = StepRecorder(case, solver, fake2)
    loop2.run_until(T_END, on_em_step=rec)
    a, b = _state(solver), _state(solver_ref)
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a), \
        [k for k in a if not np.array_equal(a[k], b[k])]
    assert np.array_equal(loop2.counters.impulse, loop_ref.counters.impulse)
    assert loop2.counters.em_steps == loop_ref.counters.em_steps == 3
    keys = ("force_x_N", "force_y_N", "force_z_N", "conservation_error_rel", "dt_s", "substeps",
            "force_density_max_N_m3", "em_mesh_min_quality")
    assert len(rec.rows) == 2
    for r, r_ref in zip(rec.rows, rows_ref[-len(rec.rows):]):
        assert all(r[k] == r_ref[k] for k in keys), (r, r_ref)
    assert np.array_equal(fake2.x_em, x_em_ref)
