"""Selective mass scaling of ten-node bodies (``ExplicitSolver3D(mass_scaling_dt=)``, :mod:`.mass_scaling`): every
cell's critical step reaches the target and only the cells below it gain mass; the scaled step bounds the
assembled mesh's largest frequency under the scaled mass; the ledger balances with the scaled mass; the compiled
steps and the Python loop give the same bits with it; a target below every cell's step is no scaling, bit for bit."""
import math

import numpy as np
import pytest
import scipy.linalg as sla

from pulseform.solvers.dolfinx import ExplicitSolver3D, ImplicitOptions, ImplicitSolver3D, Material
from cantilever_strip import Strip, regular_step, strip_body, tip_load
from pulseform.solvers.dolfinx.kernels import pack_parameters
from pulseform.solvers.dolfinx.tet10 import HRZ_SHARES, QP_DERIVATIVES, QP_WEIGHTS
from pulseform.solvers.dolfinx.tet10_kernel import tet10_cell_steps, tet10_step
from pulseform.solvers.dolfinx.tet_kernel import MODE_SOLID
from pulseform.solvers.dolfinx.tet_fields import tet_volumes

E, NU = 200e9, 0.3
G, K = E / (2 * (1 + NU)), E / (3 * (1 - 2 * NU))
ELASTIC = Material(7800.0, G, K, 1e12, 0.0)
STEEL = Material(7800.0, G, K, 250e6, 2e9)
#: a short strip whose root bricks are crowded (x = L s^2.5): its first brick 1/32 of the last's length
ST = Strip(length=0.004, width=0.001, n_length=4, n_width=1, n_thick=2, grading=2.5)


def _cell_steps(s: ExplicitSolver3D, scaled: bool) -> np.ndarray:
    """Each cell's critical step (CFL 1, at rest), s, with the solver's density factors or without."""
    b, k = s.bodies["strip"], s._kernels["strip"]
    out = np.empty(len(b.cells))
    assert tet10_cell_steps(b.cells, b.X0, s._prm["strip"], k.factor, k.rho_scale if scaled else np.empty(0), out)
    return out


def test_every_cell_reaches_the_target_and_only_the_cells_below_it_gain_mass():
    """Target: the regular bricks' step (the outer half's smallest). Every cell's scaled step >= the target (to
    1e-12), the scaled ones at it; the density factors are (target / step)^2 below it and exactly 1 elsewhere; the
    lumped mass is the HRZ mass of the scaled densities, the nodes of unscaled cells only keep their mass bit for bit,
    the mass added (kg and fraction, as logged) is rho sum (s - 1) V; the stable step is cfl x the target."""
    s0 = ExplicitSolver3D([strip_body(ST, STEEL, "tet10")], cfl=0.8)
    target = regular_step(s0, ST)
    s = ExplicitSolver3D([strip_body(ST, STEEL, "tet10")], cfl=0.8, mass_scaling_dt=target)
    b0, b = s0.bodies["strip"], s.bodies["strip"]
    dt0, dt = _cell_steps(s0, False), _cell_steps(s, True)
    scale = s._kernels["strip"].rho_scale
    below = dt0 < target
    assert np.count_nonzero(dt0 < 0.5 * target) >= 12          # the root bricks: far below it
    assert np.all(dt >= target * (1 - 1e-12))
    assert np.allclose(dt[below], target, rtol=1e-12, atol=0.0)
    assert np.array_equal(dt[~below], dt0[~below])
    assert np.array_equal(scale[~below], np.ones(np.count_nonzero(~below)))
    assert np.allclose(scale[below], (target / dt0[below]) ** 2, rtol=1e-14, atol=0.0)
    vol = tet_volumes(b.cells, b.X0)
    expected = np.bincount(b.cells.ravel(), weights=(STEEL.density * scale * vol)[:, None].repeat(10, 1).ravel()
                           * np.tile(HRZ_SHARES, len(vol)), minlength=len(b.x))
    assert np.allclose(b.mass, expected, rtol=1e-13, atol=0.0)
    untouched = np.setdiff1d(np.arange(len(b.x)), b.cells[below].ravel())
    assert len(untouched) > 0 and np.array_equal(b.mass[untouched], b0.mass[untouched])
    added = STEEL.density * float(np.sum((scale - 1.0) * vol))
    ms = s.mass_scaling["strip"]
    assert ms["cells"] == np.count_nonzero(below)
    assert ms["added_kg"] == pytest.approx(added, rel=1e-12)
    assert b.mass.sum() - b0.mass.sum() == pytest.approx(added, rel=1e-9)
    assert ms["added_fraction"] == pytest.approx(added / b0.mass.sum(), rel=1e-9)
    assert s.stable_time_step() == pytest.approx(0.8 * target, rel=1e-12)
    assert s0.stable_time_step() < 0.5 * s.stable_time_step()


def test_a_density_factor_is_a_denser_material_in_the_kernel():
    """The kernel with every cell's density factor s equals the unscaled kernel of a material s times as dense
    (rho enters the step only through the wave speed and the bulk viscosity): forces, stress, plastic strain, the
    plastic and viscous work and the critical step to round-off, under a random velocity field (compression and
    expansion, the quadratic bulk viscosity on), and differs from the unscaled material's (forces; a critical step
    over twice as long, at most sqrt(s) times)."""
    b = ExplicitSolver3D([strip_body(ST, STEEL, "tet10")]).bodies["strip"]
    rng = np.random.default_rng(3)
    v = 20.0 * rng.standard_normal(b.X0.shape)
    dt, factor, s = 2e-9, 0.3, 7.5
    dense = Material(STEEL.density * s, G, K, 250e6, 2e9)
    out = []
    for mat, scale in ((STEEL, np.full(len(b.cells), s)), (dense, np.empty(0)), (STEEL, np.empty(0))):
        prm = pack_parameters(mat, MODE_SOLID, 1.0, 0.06, 1.2, True)
        stress = 2e8 * np.tile([1.0, -0.5, 0.2, 0.3, 0.0, 0.1], (4 * len(b.cells), 1))
        ep, f, acc = np.zeros(4 * len(b.cells)), np.zeros_like(b.X0), np.zeros(3)
        d = tet10_step(b.cells, b.X0 + dt * v, v, dt, prm, stress, ep, f, acc, np.empty(0), QP_DERIVATIVES,
                       QP_WEIGHTS, factor, scale)
        out.append((f, stress, ep, acc[:2].copy(), d))
    assert out[0][2].max() > 0 and out[0][3][1] > 0
    for x, y in zip(out[0], out[1]):
        assert np.allclose(x, y, rtol=1e-13, atol=0.0)
    assert not np.allclose(out[0][0], out[2][0], rtol=1e-6, atol=0.0)
    # the critical step: sqrt(s) times longer at most (the quadratic bulk viscosity's xi grows with le / c_e)
    assert 2.0 * out[2][4] < out[0][4] <= math.sqrt(s) * out[2][4]


def test_scaled_step_bounds_the_largest_frequency_of_the_scaled_mesh():
    """The scaled solver's critical step (CFL 1, no bulk viscosity) does not exceed 2 / omega_max of the assembled
    elastic stiffness under the scaled lumped mass (scipy's dense eigensolver), and is within a factor two of it:
    the scaled mesh is stable at its step and the scaling did not overshoot."""
    s0 = ExplicitSolver3D([strip_body(ST, ELASTIC, "tet10")], bulk_viscosity=False, cfl=1.0)
    target = regular_step(s0, ST)
    s = ExplicitSolver3D([strip_body(ST, ELASTIC, "tet10")], bulk_viscosity=False, cfl=1.0, mass_scaling_dt=target)
    si = ImplicitSolver3D([strip_body(ST, ELASTIC, "tet10")], ImplicitOptions(dt=1.0, scheme="static"))
    bi = si.bodies["strip"]
    Kt = si._assemble([("strip", bi, si._cells("strip", bi, np.zeros(bi.cells.shape + (3,)), 1.0))], 0.0,
                      1.0).toarray()
    w2 = sla.eigh(0.5 * (Kt + Kt.T), np.diag(np.repeat(s.bodies["strip"].mass, 3)), eigvals_only=True)[-1]
    w2_0 = sla.eigh(0.5 * (Kt + Kt.T), np.diag(np.repeat(s0.bodies["strip"].mass, 3)), eigvals_only=True)[-1]
    dt = s.stable_time_step()
    assert dt <= 2.0 / math.sqrt(w2) * (1 + 1e-12)
    assert dt >= 0.5 * 2.0 / math.sqrt(w2)
    assert 2.0 / math.sqrt(w2) > 2.0 * 2.0 / math.sqrt(w2_0)          # the mesh's own step lengthened too


def _driven(compiled: bool, target: float | None) -> ExplicitSolver3D:
    """The strip under tip forces past first yield (M_p / L = 15.6 N; bulk viscosity on), then kinetic damping."""
    s = ExplicitSolver3D([strip_body(ST, STEEL, "tet10")], cfl=0.8, compiled_steps=compiled, mass_scaling_dt=target)
    b = s.bodies["strip"]
    s.advance(s.stable_time_step(), 400, {"strip": tip_load(b, ST, 8.0)})
    s.advance(s.stable_time_step(), 600, {"strip": tip_load(b, ST, 14.0)})
    s.kinetic_damping = True
    s.advance(s.stable_time_step(), 1500, {"strip": tip_load(b, ST, 12.0)})
    return s


def _same(s1: ExplicitSolver3D, s2: ExplicitSolver3D) -> bool:
    b1, b2 = s1.bodies["strip"], s2.bodies["strip"]
    arrays = all(np.array_equal(getattr(b1, k), getattr(b2, k))
                 for k in ("x", "v", "a", "mass", "cell_stress", "eps_p", "temperature"))
    return arrays and (s1.time, s1.step_count, s1._dt_crit, s1.energies()) == (s2.time, s2.step_count,
                                                                               s2._dt_crit, s2.energies())


def test_free_vibration_ledger_balances_with_the_scaled_mass():
    """The strip set moving at 1 m/s across (-z; the root's axis nodes held: it swings and rings), elastic, no bulk
    viscosity, scaled: the initial energy is the kinetic energy of the scaled mass (23 % added, the root's cells
    moving as fast as the rest: the unscaled mass would be 19 % short of it), and the ledger balances to 1e-4 of it
    over 1000 steps, by which part of it is elastic."""
    s0 = ExplicitSolver3D([strip_body(ST, ELASTIC, "tet10")], bulk_viscosity=False)
    s = ExplicitSolver3D([strip_body(ST, ELASTIC, "tet10")], bulk_viscosity=False,
                         mass_scaling_dt=regular_step(s0, ST))
    b = s.bodies["strip"]
    free = ~b.constrained_mask()[:, 2]
    b.v[free, 2] = -1.0
    s._init_start()
    ke = 0.5 * float(np.sum(b.mass[free]))
    assert s.initial_energy == pytest.approx(ke, rel=1e-12)
    assert s.mass_scaling["strip"]["added_fraction"] > 0.2
    assert 0.5 * float(np.sum(s0.bodies["strip"].mass[free])) < 0.85 * ke
    s.advance(s.stable_time_step(), 1000)
    e = s.energies()
    assert e["elastic_J"] > 0.05 * ke
    assert abs(e["balance_error_J"]) <= 1e-4 * ke


def test_compiled_steps_and_off_with_mass_scaling():
    """Scaled, through plastic flow, bulk viscosity and kinetic damping: the compiled steps and the Python loop give
    the same bits. A target below every cell's step scales nothing (no density factors) and runs the unscaled
    bits; the scaled run differs from them."""
    s0 = ExplicitSolver3D([strip_body(ST, STEEL, "tet10")])
    target = regular_step(s0, ST)
    s1, s2 = _driven(True, target), _driven(False, target)
    assert s1._steps is not None and s2._steps is None
    e = s1.energies()
    assert s1.bodies["strip"].eps_p.max() > 0 and e["kinetic_damping_J"] > 0 and e["viscous_J"] > 0
    assert _same(s1, s2)
    assert s1._dt_crit > 0.75 * target > 1.5 * float(_cell_steps(s0, False).min())   # the deformed mesh's, scaled
    low = 0.5 * float(_cell_steps(s0, False).min())
    off, none = _driven(True, low), _driven(True, None)
    assert off.mass_scaling["strip"] == {"cells": 0, "added_kg": 0.0, "added_fraction": 0.0}
    assert off._kernels["strip"].rho_scale.size == 0
    assert _same(off, none)
    assert not _same(s1, none)


def test_restart_of_a_scaled_run_is_exact_and_checked():
    """A scaled run's state loaded into a fresh solver of the same target continues as the uninterrupted run, bit for
    bit; a solver without the scaling, or of another target, refuses it (its masses would differ)."""
    s0 = ExplicitSolver3D([strip_body(ST, STEEL, "tet10")])
    target = regular_step(s0, ST)
    s1 = _driven(True, target)
    saved = s1.state_dict()
    s1.advance(s1.stable_time_step(), 300, {"strip": tip_load(s1.bodies["strip"], ST, 10.0)})
    s2 = ExplicitSolver3D([strip_body(ST, STEEL, "tet10")], cfl=0.8, mass_scaling_dt=target)
    s2.load_state_dict(saved)
    s2.kinetic_damping = True                     # a setting, not state
    s2.advance(s2.stable_time_step(), 300, {"strip": tip_load(s2.bodies["strip"], ST, 10.0)})
    assert _same(s1, s2)
    assert "strip/mass_scale" not in s0.state_dict()
    for other in (None, 0.9 * target):
        with pytest.raises(ValueError, match="selective mass scaling"):
            ExplicitSolver3D([strip_body(ST, STEEL, "tet10")], mass_scaling_dt=other).load_state_dict(saved)
    with pytest.raises(ValueError, match="selective mass scaling"):
        ExplicitSolver3D([strip_body(ST, STEEL, "tet10")], mass_scaling_dt=target).load_state_dict(s0.state_dict())


def test_mass_scaling_is_checked():
    """A non-positive target and a body of linear tetrahedra are refused."""
    with pytest.raises(ValueError, match="mass_scaling_dt must be > 0"):
        ExplicitSolver3D([strip_body(ST, STEEL, "tet10")], mass_scaling_dt=0.0)
    with pytest.raises(ValueError, match="linear tetrahedra"):
        ExplicitSolver3D([strip_body(ST, STEEL, "tet4")], mass_scaling_dt=1e-8)


def test_case_key_reaches_the_solver_and_is_checked(tmp_path):
    """``mechanics.mass_scaling_dt`` from a case file: the 3D bar of cases/bar_impact_3d on ten-node cells (coarse),
    relaxed by kinetic damping against its wall, with a target of 2e-5 s above every cell's step: the run steps at
    cfl x target (0.5 x 2e-5 s, to 1e-9; unscaled: 4.06e-6 s) and its log gives the added mass. Misuse is one line
    naming the key: a 2D case, a linear body, no damping (the dynamics would change), a coupled case (checked in
    tests/foundation/test_bad_input.py's style here with `pulseform check`)."""
    import csv
    import subprocess
    import sys
    from pathlib import Path

    exe = str(Path(sys.executable).with_name("pulseform"))
    repo = Path(__file__).resolve().parents[2]
    base = [exe, "run", str(repo / "cases/bar_impact_3d"), "--quiet", "--set", "output.plots=false",
            "--set", "bodies[0].mesh_size=0.5", "--set", "mechanics.kinetic_damping_until=1",
            "--set", "time.end=2e-4"]
    out = tmp_path / "scaled"
    r = subprocess.run([*base, "--out", str(out), "--set", "bodies[0].element='tet10'",
                        "--set", "mechanics.mass_scaling_dt=2e-5"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    rows = list(csv.DictReader(open(out / "history.csv")))
    assert float(rows[1]["dt_s"]) == pytest.approx(0.5 * 2e-5, rel=1e-9)
    assert "selective mass scaling of" in (out / "run.log").read_text()
    for sets, key in ((["--set", "mechanics.kinetic_damping_until=1"], "bodies[0].element"),
                      (["--set", "bodies[0].element='tet10'", "--set", "mechanics.kinetic_damping_until=0"],
                       "mechanics.mass_scaling_dt")):
        r = subprocess.run([exe, "check", str(repo / "cases/bar_impact_3d"), "--set", "mechanics.mass_scaling_dt=2e-5",
                            *sets], capture_output=True, text=True, timeout=300)
        lines = [ln for ln in r.stderr.splitlines() if ln.startswith("pulseform: error:")]
        assert r.returncode == 2 and len(lines) == 1 and key in lines[0] and "Traceback" not in r.stderr, r.stderr
    for case in ("bar_impact", "emf_sheet_bulge"):
        r = subprocess.run([exe, "check", str(repo / "cases" / case), "--set", "mechanics.mass_scaling_dt=2e-5"],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 2 and "mechanics.mass_scaling_dt" in r.stderr and "Traceback" not in r.stderr
