"""3D deck, BDF2 (Resolution EM_Transient3D_BDF2: equal steps, the first one implicit Euler).

References:
- the capacitor bank into a sector coil in air (linear, instantaneous: an R-L-C series circuit with
  L = 2 W s / I^2, R = P s / I^2 from GetDP, s the symmetry factor): the BDF2 recurrence of that
  circuit computed with numpy, (3 x_n - 4 x_{n-1} + x_{n-2}) / (2 dt) after an implicit Euler step;
- eddy currents in a disk under the demo's coil (prescribed current), slow tier: self-convergence in
  dt of the disk's force history; the observed order must be second (Euler's: first).
"""
import numpy as np
import pytest

from pulseform.solvers.getdp import Circuit, Conductor, DampedSine, Rect
from pulseform.solvers.getdp.mesh3d import ring_sector_mesh
from pulseform.solvers.getdp.solver3d import Coil3D, EM3DModel, solve_transient3d

from getdp_testlib import needs_getdp
from test_em3d_static import demo_coil_turns

C, V0, R_EXT, L_EXT = 100e-6, 5e3, 5e-3, 2e-6


def rlc_bdf2(L: float, R: float, dt: float, n: int) -> np.ndarray:
    """Current of the series RLC discharge (C charged to V0) by BDF2 with an implicit Euler first step."""
    i, v = [0.0], [V0]
    for k in range(n):
        if k == 0:
            a, b = [[R + L / dt, -1.0], [dt / C, 1.0]], [L / dt * i[-1], v[-1]]
        else:
            a = [[R + 1.5 * L / dt, -1.0], [1.0, 1.5 * C / dt]]
            b = [L / dt * (2 * i[-1] - 0.5 * i[-2]), C / dt * (2 * v[-1] - 0.5 * v[-2])]
        x = np.linalg.solve(a, b)
        i.append(x[0])
        v.append(x[1])
    return np.array(i[1:])


@pytest.mark.getdp
@needs_getdp
def test_bdf2_bank_discharge_vs_recurrence(work):
    mesh = ring_sector_mesh(work / "coil.msh", demo_coil_turns(), [], sector_deg=30.0, h_coil=3e-3, h_air=0.02)
    model = EM3DModel(coils=[Coil3D(5)], circuit=Circuit(C, V0, R_EXT, L_EXT), shell=(0.1, 0.125), sector_deg=30.0)
    n, t_end = 20, 40e-6
    res = solve_transient3d(model, mesh, t_end, n, work / "run", time_scheme="bdf2")
    i = res.coil_current[:, 0]
    s = model.symmetry_factor
    L = 2 * res.magnetic_energy[-1] * s / i[-1] ** 2 + L_EXT
    R = res.coil_power[-1, 0] * s / i[-1] ** 2 + R_EXT
    ref = rlc_bdf2(L, R, t_end / n, n)
    err = np.abs(i - ref).max() / np.abs(ref).max()
    print(f"\nBDF2, bank into a 30 deg sector coil: max |I - I_bdf2| / max |I| = {err:.1e}")
    np.testing.assert_allclose(res.times, np.arange(1, n + 1) * t_end / n, rtol=1e-12)
    assert err < 1e-9


@pytest.mark.slow
@pytest.mark.getdp
@needs_getdp
def test_bdf2_force_second_order_in_dt(work):
    """Successive differences of the force history on the common 2 us grid (0..12 us), dt = 2, 1, 0.5,
    0.25, 0.125 us: their ratios give the order (observed: BDF2 1.83, 2.11, 2.03; Euler 0.84, 0.91, 0.96)."""
    mesh = ring_sector_mesh(work / "disk.msh", demo_coil_turns(), [Rect(0.0, 0.0, 0.06, 0.001)], sector_deg=10.0,
                            h_coil=3e-3, h_conductor=2e-3, h_air=0.02, conductor_layers=2)
    model = EM3DModel(coils=[Coil3D(5, waveform=DampedSine(20e3, 1e4, 1e5))], conductors=[Conductor(3.5e7)],
                      shell=(0.1, 0.125), sector_deg=10.0)
    t_end, ns = 12e-6, (6, 12, 24, 48, 96)
    orders = {}
    for scheme in ("bdf2", "euler"):
        g = {}
        for n in ns:
            res = solve_transient3d(model, mesh, t_end, n, work / f"{scheme}{n}", element_output="none",
                                    time_scheme=scheme)
            g[n] = res.conductor_force[n // 6 - 1::n // 6, 0, 2]     # at 2, 4, ..., 12 us
        diffs = np.array([np.abs(g[a] - g[b]).max() for a, b in zip(ns[:-1], ns[1:])])
        orders[scheme] = np.log2(diffs[:-1] / diffs[1:])
        print(f"\n{scheme}: max successive differences {diffs} N; orders {orders[scheme]}")
    assert np.all(orders["bdf2"] > 1.7)
    assert np.all(orders["euler"] < 1.2)
