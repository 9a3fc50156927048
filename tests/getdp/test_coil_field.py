"""Static field of a 10-turn coil vs Biot-Savart; truncation error of the open boundary.

Reference: the field of a circular filament (Smythe, Static and Dynamic Electricity, 7.10:
B_z, B_r with complete elliptic integrals K(m), E(m), scipy.special.ellipk/ellipe), integrated
over each turn's rectangular cross-section with 8 x 8 Gauss points (uniform current density,
as in the stranded-coil model).  No conductor is present, so the transient solution at any
time is the static field of the current at that time.
"""
import numpy as np
import pytest
from scipy.special import ellipe, ellipk

from pulseform.solvers.getdp import Coil, CurrentTable, EMModel, GetDPSolver, coil_conductor_mesh

from getdp_testlib import needs_getdp, ten_turn_coil

MU0 = 4e-7 * np.pi
I_TURN = 1e4


def loop_field(a, z0, r, z):
    """(B_r, B_z) of a 1 A filament of radius a at height z0, current along +e_phi."""
    zz = z - z0
    m = 4 * a * r / ((a + r) ** 2 + zz ** 2)
    k, e = ellipk(m), ellipe(m)
    den = np.sqrt((a + r) ** 2 + zz ** 2)
    q = (a - r) ** 2 + zz ** 2
    bz = MU0 / (2 * np.pi * den) * (k + (a * a - r * r - zz * zz) / q * e)
    br = MU0 * zz / (2 * np.pi * r * den) * (-k + (a * a + r * r + zz * zz) / q * e)
    return br, bz


def biot_savart(turns, current, r, z, n_gauss=8):
    g, w = np.polynomial.legendre.leggauss(n_gauss)
    b = np.zeros(2)
    for t in turns:
        area = (t.x1 - t.x0) * (t.y1 - t.y0)
        for gi, wi in zip(g, w):
            a = 0.5 * (t.x0 + t.x1) + 0.5 * (t.x1 - t.x0) * gi
            for gj, wj in zip(g, w):
                zc = 0.5 * (t.y0 + t.y1) + 0.5 * (t.y1 - t.y0) * gj
                b += current / area * wi * wj * area / 4 * np.array(loop_field(a, zc, r, z))
    return b


def test_loop_formula_matches_direct_biot_savart():
    """The elliptic-integral filament field vs a direct sum of Biot-Savart segments."""
    a, r, z = 0.025, 0.03, 0.015
    ph = np.linspace(0, 2 * np.pi, 20001)[:-1]
    src = np.stack([a * np.cos(ph), a * np.sin(ph), 0 * ph], 1)
    dl = np.stack([-a * np.sin(ph), a * np.cos(ph), 0 * ph], 1) * (ph[1] - ph[0])
    rr = np.array([r, 0, z]) - src
    b = (MU0 / (4 * np.pi) * np.cross(dl, rr) / np.linalg.norm(rr, axis=1)[:, None] ** 3).sum(0)
    np.testing.assert_allclose(loop_field(a, 0.0, r, z), [b[0], b[2]], rtol=1e-9)


def coil_centre_field(work, shell: bool, r_domain: float):
    turns = ten_turn_coil()
    mesh = coil_conductor_mesh([turns], [], r_domain=r_domain, r_shell=1.25 * r_domain if shell else None,
                               h_fine=5e-4, h_coarse=3e-3)
    model = EMModel(True, coils=[Coil(10, waveform=CurrentTable([0, 1], [I_TURN, I_TURN]))],
                    shell=(r_domain, 1.25 * r_domain) if shell else None, probes=[(1e-5, 0.0)])
    solver = GetDPSolver(model, work)
    res, _ = solver.step(mesh, solver.initial_state(), 1e-6, 1, run_name=f"shell{int(shell)}_{r_domain:g}")
    # GetDP frame (r, z, .): a positive coil current flows along -e_phi, so B flips sign.
    bz = -res.probe_b[-1, 0, 1]
    ref = biot_savart(turns, I_TURN, 1e-5, 0.0)[1]
    return bz, ref, mesh.n_nodes, 2 * res.magnetic_energy[-1] / I_TURN ** 2


@pytest.mark.getdp
@needs_getdp
def test_centre_field_vs_biot_savart_with_shell(work):
    bz, ref, n, ind = coil_centre_field(work, shell=True, r_domain=0.05)
    err = bz / ref - 1
    print(f"\nB_z centre: GetDP {bz:.6f} T, Biot-Savart {ref:.6f} T, rel. error {err:+.3%} ({n} nodes, "
          f"shell 50-62.5 mm); L = {ind * 1e6:.4f} uH")
    assert abs(err) < 0.01


@pytest.mark.getdp
@needs_getdp
def test_truncation_without_shell_is_worse(work):
    """Same inner mesh with a = 0 at R = 50 mm instead of the shell: the truncation error shows."""
    bz, ref, n, ind = coil_centre_field(work, shell=False, r_domain=0.05)
    err = bz / ref - 1
    print(f"\nB_z centre with a = 0 at 50 mm: rel. error {err:+.3%}; L = {ind * 1e6:.4f} uH")
    assert err < -0.05
