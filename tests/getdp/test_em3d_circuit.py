"""3D deck: the capacitor bank discharging into a coil modelled on a sector (symmetry factor).

The coil's voltage in the circuit is the whole coil's: ``SymmetryFactor`` x the sector's. With the
coil in air the field is linear and instantaneous, so the coil is an inductance L and a resistance
R of the whole device, which GetDP's own outputs give on the same mesh: L = 2 W s / I^2 and
R = P s / I^2 (W, P: magnetic energy and Joule power of the sector, s = 360 / 30 = 12); for the
Galerkin solution 2 W = I x (flux linkage of the sector), so this L is exactly the discrete one.

Reference: the series R-L-C circuit (standard circuit theory) discretised like the deck, implicit
Euler: C (V_n - V_{n-1}) / dt = -I_n, V_n = (R + R_ext) I_n + (L + L_ext)(I_n - I_{n-1}) / dt,
computed here with numpy; and R vs the rings' analytic resistance. A wrong symmetry factor in the coil equation would change the circuit's
inductance and resistance by that factor (12).
"""
import numpy as np
import pytest

from pulseform.solvers.getdp import Circuit
from pulseform.solvers.getdp.mesh3d import ring_sector_mesh
from pulseform.solvers.getdp.solver3d import Coil3D, EM3DModel, solve_transient3d

from getdp_testlib import needs_getdp
from test_em3d_static import demo_coil_turns

C, V0, R_EXT, L_EXT = 100e-6, 5e3, 5e-3, 2e-6


@pytest.mark.getdp
@needs_getdp
def test_bank_discharge_into_sector_coil(work):
    mesh = ring_sector_mesh(work / "coil3d.msh", demo_coil_turns(), [], sector_deg=30.0, r_air=0.1, r_shell=0.125,
                            h_coil=3e-3, h_air=0.02)
    model = EM3DModel(coils=[Coil3D(5)], circuit=Circuit(C, V0, R_EXT, L_EXT), shell=(0.1, 0.125), sector_deg=30.0)
    n, t_end = 40, 40e-6
    res = solve_transient3d(model, mesh, t_end, n, work / "run")
    i = res.coil_current[:, 0]
    s = model.symmetry_factor
    l_coil = 2 * res.magnetic_energy * s / i ** 2
    r_coil = res.coil_power[:, 0] * s / i ** 2
    assert np.ptp(l_coil) < 1e-8 * l_coil.mean() and np.ptp(r_coil) < 1e-8 * r_coil.mean()
    L, R, dt = l_coil[-1] + L_EXT, r_coil[-1] + R_EXT, t_end / n
    ref, v, ip = [], V0, 0.0
    for _ in range(n):   # [[R + L/dt, -1], [dt/C, 1]] [I, V] = [L/dt I_prev, V_prev]
        ip, v = np.linalg.solve([[R + L / dt, -1.0], [dt / C, 1.0]], [L / dt * ip, v])
        ref.append(ip)
    ref = np.array(ref)
    err = np.abs(i - ref).max() / np.abs(ref).max()
    print(f"\nsector 30 deg, {mesh.n_tets} tets: L_coil {l_coil[-1] * 1e6:.4f} uH, R_coil {r_coil[-1] * 1e3:.4f} mOhm,"
          f" peak {i.max() / 1e3:.3f} kA; max |I - I_rlc| / max |I_rlc| = {err:.2e}")
    assert i.max() > 0
    assert err < 1e-8
    # the whole coil's resistance, analytic: uniform current density I / A in each ring turn of section A
    # and centroid radius r_c gives R = sum 2 pi r_c / (sigma A) (5.8e7 S/m, A = 12 mm^2)
    r_ref = sum(2 * np.pi * 0.5 * (t.x0 + t.x1) / (5.8e7 * 12e-6) for t in demo_coil_turns())
    print(f"R_coil vs analytic {r_ref * 1e3:.4f} mOhm: {r_coil[-1] / r_ref - 1:+.3%}")
    assert r_coil[-1] == pytest.approx(r_ref, rel=3e-3)
    # the capacitor voltage closes the loop: V_C = U_coil + R_ext I + L_ext dI/dt
    di = np.diff(np.concatenate([[0.0], i])) / dt
    loop = res.capacitor_voltage - (res.coil_voltage[:, 0] + R_EXT * i + L_EXT * di)
    assert np.abs(loop).max() < 1e-6 * V0
