"""Longer verification runs (``-m slow``).

- Energy balance of the capacitor discharge into coil + disk: the error is implicit Euler's
  numerical dissipation, so it must fall at first order in dt (reference: conservation).
- Coil over a disk: peak axial force under mesh refinement at dt = 0.5 us must converge (successive
  changes shrinking), and action = reaction (Newton's third law: the force on the coil balances the
  force on the disk, the field carrying no net momentum in the quasi-static limit) within 0.5 %.
"""
import numpy as np
import pytest

from pulseform.solvers.getdp import (Circuit, Coil, Conductor, DampedSine, EMModel, GetDPSolver, Rect,
                                     coil_conductor_mesh)

from getdp_testlib import needs_getdp, ten_turn_coil


@pytest.mark.slow
@pytest.mark.getdp
@needs_getdp
def test_energy_error_first_order_in_dt(work):
    C, V0, R_EXT, L_EXT = 100e-6, 5e3, 5e-3, 2e-6
    mesh = coil_conductor_mesh([ten_turn_coil()], [Rect(0.0, 0.0035, 0.06, 0.0045)], r_domain=0.1, r_shell=0.125,
                               h_fine=1e-3, h_coarse=1.5e-2, h_conductor=1e-3)
    model = EMModel(True, coils=[Coil(10)], conductors=[Conductor(3.5e7)], circuit=Circuit(C, V0, R_EXT, L_EXT),
                    shell=(0.1, 0.125))
    solver = GetDPSolver(model, work, keep_runs=1)
    errs = []
    ns = [1000, 2000, 4000]
    for n in ns:
        res, _ = solver.step(mesh, solver.initial_state(), 100e-6, n, run_name=f"n{n}", element_output="none")
        i = res.coil_current[:, 0]
        joule = np.cumsum((res.coil_power[:, 0] + res.conductor_power.sum(axis=1) + R_EXT * i ** 2) * res.dt)
        total = 0.5 * C * res.capacitor_voltage ** 2 + res.magnetic_energy + 0.5 * L_EXT * i ** 2 + joule
        errs.append(np.abs(total / (0.5 * C * V0 ** 2) - 1).max())
    rate = np.polyfit(np.log(ns), np.log(errs), 1)[0]
    print(f"\nenergy balance max rel. errors {errs} for {ns} steps: order in dt {-rate:.3f}")
    assert 0.9 < -rate < 1.1
    assert errs[-1] < 0.005


@pytest.mark.slow
@pytest.mark.getdp
@needs_getdp
def test_coil_over_disk_force_converges_and_balances(work):
    turns = [Rect(0.010 + i * 0.004, -0.003, 0.013 + i * 0.004, -0.001) for i in range(5)]
    disk = Rect(0.0, 0.0, 0.06, 0.001)
    model = EMModel(True, coils=[Coil(5, waveform=DampedSine(20e3, 1e4, 1e5))], conductors=[Conductor(3.5e7)],
                    shell=(0.15, 0.1875))
    solver = GetDPSolver(model, work, keep_runs=1)
    peaks, nodes, imbalance = [], [], []
    for s in (1.0, 0.5, 0.25):
        mesh = coil_conductor_mesh([turns], [disk], r_domain=0.15, r_shell=0.1875, h_fine=1e-3 * s,
                                   h_coarse=1e-2, h_conductor=5e-4 * s)
        res, _ = solver.step(mesh, solver.initial_state(), 20e-6, 40, run_name=f"s{s}")
        fz = res.conductor_force[:, 0, 1]
        k = fz.argmax()
        peaks.append(fz[k])
        imbalance.append(abs(fz[k] + res.coil_force[k, 0, 1]) / fz[k])
        nodes.append(mesh.n_nodes)
    d1, d2 = abs(peaks[1] - peaks[0]), abs(peaks[2] - peaks[1])
    print(f"\npeak F_z on the disk {[f'{p:.1f}' for p in peaks]} N on {nodes} nodes, changes {d1:.1f}, {d2:.1f} N;"
          f" |F_disk + F_coil| / F_disk = {[f'{x:.2e}' for x in imbalance]}")
    assert d2 < 0.5 * d1
    assert imbalance[-1] < 5e-3
