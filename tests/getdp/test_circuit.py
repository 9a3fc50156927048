"""Capacitor-bank discharge through the coil (GetDP circuit equations).

References:
- RLC: the series under-damped discharge of C charged to V0 (standard circuit theory),
  i(t) = V0 / (omega_d L) exp(-alpha t) sin(omega_d t), alpha = R / (2 L), omega_d^2 = 1/(LC) - alpha^2,
  with L = L_ext + L_coil and R = R_ext + R_coil, where L_coil = 2 W_mag / I^2 and
  R_coil = P_coil / I^2 are computed by GetDP on the same mesh (coil in air, no conductor).
- Energy: conservation, 1/2 C V0^2 = 1/2 C V_C^2 + W_mag (field) + 1/2 L_ext I^2
  + Joule losses so far (coil + disk eddy currents + R_ext), with a rigid disk over the coil.
  Joule losses are accumulated with the rectangle rule over the implicit Euler sub-steps.
Implicit Euler is first order: its numerical dissipation is O(dt); dt is chosen for < 1 %.
"""
import numpy as np
import pytest

from pulseform.solvers.getdp import (Circuit, Coil, Conductor, EMModel, GetDPSolver, Rect,
                                     coil_conductor_mesh, em_metrics)

from getdp_testlib import needs_getdp, ten_turn_coil

C, V0, R_EXT, L_EXT = 100e-6, 5e3, 5e-3, 2e-6
T_END = 100e-6   # beyond the first current peak, ~0.55 of a period


@pytest.mark.getdp
@needs_getdp
def test_rlc_discharge_vs_analytic(work):
    mesh = coil_conductor_mesh([ten_turn_coil()], [], r_domain=0.05, r_shell=0.0625, h_fine=1e-3, h_coarse=1e-2)
    model = EMModel(True, coils=[Coil(10)], circuit=Circuit(C, V0, R_EXT, L_EXT), shell=(0.05, 0.0625))
    solver = GetDPSolver(model, work)
    res, state = solver.step(mesh, solver.initial_state(), T_END, 1000)
    i = res.coil_current[:, 0]
    l_coil = 2 * res.magnetic_energy / i ** 2
    r_coil = res.coil_power[:, 0] / i ** 2
    assert np.ptp(l_coil) < 1e-9 * l_coil.mean() and np.ptp(r_coil) < 1e-9 * r_coil.mean()  # linear, in air
    L, R = L_EXT + l_coil[-1], R_EXT + r_coil[-1]
    alpha = R / (2 * L)
    wd = np.sqrt(1 / (L * C) - alpha ** 2)
    ref = V0 / (wd * L) * np.exp(-alpha * res.times) * np.sin(wd * res.times)
    err = np.abs(i - ref).max() / np.abs(ref).max()
    print(f"\nL_coil = {l_coil[-1] * 1e6:.4f} uH, R_coil = {r_coil[-1] * 1e3:.4f} mOhm, peak {i.max() / 1e3:.3f} kA"
          f" (analytic {ref.max() / 1e3:.3f} kA); max |I - i| / max|i| = {err:.3%} (dt = {res.dt:.2e} s)")
    assert err < 0.01
    # the coil voltage drop is R I + d(flux)/dt, and the series loop closes: V_C = U_coil + R_ext I + L_ext dI/dt
    di = np.diff(np.concatenate([[0.0], i])) / res.dt
    loop = res.capacitor_voltage - (res.coil_voltage[:, 0] + R_EXT * i + L_EXT * di)
    assert np.abs(loop).max() < 1e-6 * V0
    m = em_metrics([res])
    assert m["coil_current_peak_kA"] == pytest.approx(np.abs(i).max() / 1e3)
    assert m["coil_joule_heat_J"] == pytest.approx((res.coil_power[:, 0] * res.dt).sum())


@pytest.mark.slow
@pytest.mark.getdp
@needs_getdp
def test_energy_balance_with_disk(work):
    """(Slow, ~20 s: one getdp run of 2000 steps. The default tier's circuit checks: test_rlc_discharge_vs_analytic,
    test_two_coils_in_series_and_coil_heating; the coupled energy ledger in tests/coupling.)"""
    disk = Rect(0.0, 0.0035, 0.06, 0.0045)   # 1 mm Al disk, 1 mm above the coil
    # coarse mesh: the balance is a property of the discrete system; only dt sets its error
    mesh = coil_conductor_mesh([ten_turn_coil()], [disk], r_domain=0.1, r_shell=0.125, h_fine=2e-3,
                               h_coarse=2.5e-2, h_conductor=1e-3)
    model = EMModel(True, coils=[Coil(10)], conductors=[Conductor(3.5e7)], circuit=Circuit(C, V0, R_EXT, L_EXT),
                    shell=(0.1, 0.125))
    solver = GetDPSolver(model, work)
    res, _ = solver.step(mesh, solver.initial_state(), T_END, 2000, element_output="last")
    i = res.coil_current[:, 0]
    joule = np.cumsum((res.coil_power[:, 0] + res.conductor_power.sum(axis=1) + R_EXT * i ** 2) * res.dt)
    e0 = 0.5 * C * V0 ** 2
    total = 0.5 * C * res.capacitor_voltage ** 2 + res.magnetic_energy + 0.5 * L_EXT * i ** 2 + joule
    rel = np.abs(total / e0 - 1)
    print(f"\n{mesh.n_nodes} nodes, {len(res.times)} steps: energy balance max rel. error {rel.max():.3%} "
          f"(at t = {res.times[rel.argmax()] * 1e6:.1f} us); disk Joule {np.sum(res.conductor_power) * res.dt:.1f} J, "
          f"coil Joule {res.coil_heat[0]:.1f} J, of {e0:.0f} J")
    assert rel.max() < 0.01
    assert np.sum(res.conductor_power) * res.dt > 0.01 * e0   # the disk really takes energy
    # element_output="last": one row of element data, consistent with the last sub-step's totals
    vol = mesh.volumes(True)[res.elements]
    assert res.force_density.shape[0] == 1
    assert np.allclose(res.force_density[0].T @ vol, res.conductor_force[-1, 0], rtol=1e-9)


@pytest.mark.getdp
@needs_getdp
def test_two_coils_in_series_and_coil_heating(work):
    """Two coils in series with the bank: one current, the loop voltage closes (Kirchhoff).

    Reference for the temperature: adiabatic heating dT = Q / (rho c V) with V = sum 2 pi r_c A
    over the coil's triangles; Q = sum of the coil's Joule power over the sub-steps times dt.
    """
    coils = [ten_turn_coil(0.020, -0.01), ten_turn_coil(0.020, +0.01)]
    mesh = coil_conductor_mesh(coils, [], r_domain=0.06, r_shell=0.075, h_fine=1e-3, h_coarse=1e-2)
    model = EMModel(True, coils=[Coil(10), Coil(10, sigma=3.0e7)], circuit=Circuit(C, V0, R_EXT, L_EXT),
                    shell=(0.06, 0.075))
    solver = GetDPSolver(model, work)
    res, state = solver.step(mesh, solver.initial_state(), 20e-6, 100)
    i = res.coil_current
    assert np.abs(i[:, 0] - i[:, 1]).max() < 1e-9 * np.abs(i).max()
    np.testing.assert_allclose(res.circuit_current, i[:, 0], rtol=1e-9)
    di = np.diff(np.concatenate([[0.0], i[:, 0]])) / res.dt
    loop = res.capacitor_voltage - (res.coil_voltage.sum(axis=1) + R_EXT * i[:, 0] + L_EXT * di)
    assert np.abs(loop).max() < 1e-6 * V0
    # the second coil (lower conductivity) heats more
    assert res.coil_heat[1] > 1.5 * res.coil_heat[0]
    for k in range(2):
        sel = mesh.tri_tags == 101 + k
        vol = mesh.volumes(True)[sel].sum()
        q = res.coil_power[:, k].sum() * res.dt
        assert res.coil_heat[k] == pytest.approx(q, rel=1e-12)
        assert res.coil_temperature_rise[k] == pytest.approx(q / (8960.0 * 385.0 * vol), rel=1e-12)
    assert state.coil_heat == pytest.approx(list(res.coil_heat))
    print(f"\ntwo coils: I peak {np.abs(i).max() / 1e3:.2f} kA, heat {res.coil_heat} J, dT {res.coil_temperature_rise} K")
