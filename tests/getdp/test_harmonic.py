"""Time-harmonic solve (solvers/getdp/harmonic.py, Resolution EM_Harmonic) against the transient
solver: a 5-turn coil under an aluminium plate driven by a steady 2 kHz sine (1 kA per turn). The
transient run on the product's path (persistent getdp, BDF2, 40 steps per period, 8 periods: the
plate's slowest eddy mode, L/R ~ 0.8 ms, has decayed to e^-5) averaged over its last period gives
the cycle-mean axial force and Joule power of the plate that the frequency-domain solve gives
directly as 1/2 Re(j x conj(b)) and 1/2 sigma |j w a|^2. Issue 17's time-harmonic cross-check
(within 1 %). Measured: F_z 24.1336 N transient vs 24.1273 N harmonic (0.03 %). (A theta-scheme run
converges to it only at first order in dt, whatever theta: its post-processed j = -sigma Dt[a] is the
backward difference, half a step behind b: Crank-Nicolson +1.8 % at 80 steps per period, +0.9 % at
160; implicit Euler -0.4 % at 160.)"""
import math

import numpy as np
import pytest

from pulseform.solvers.getdp import Circuit, Coil, Conductor, DampedSine, EMModel, Rect, coil_conductor_mesh
from pulseform.solvers.getdp.harmonic import sine_phasor, solve_harmonic
from pulseform.solvers.getdp.persistent import PersistentGetDPSolver

from getdp_testlib import needs_getdp

F, I0 = 2e3, 1e3
TURNS = [Rect(0.010 + i * 0.004, -0.003, 0.013 + i * 0.004, -0.001) for i in range(5)]
PLATE = Rect(0.0, 0.0, 0.06, 0.002)


@pytest.mark.getdp
@needs_getdp
def test_cycle_mean_force_equals_frequency_domain(work):
    w = 2 * math.pi * F
    mesh = coil_conductor_mesh([TURNS], [PLATE], r_domain=0.15, r_shell=0.1875, h_fine=1.5e-3, h_coarse=2.5e-2,
                               h_conductor=1e-3)
    model = EMModel(True, coils=[Coil(5, waveform=DampedSine(I0, 0.0, w))], conductors=[Conductor(3.5e7)],
                    shell=(0.15, 0.1875))
    harm = solve_harmonic(model, mesh, F, [sine_phasor(I0)], work / "harmonic")
    periods, per = 8, 40
    solver = PersistentGetDPSolver(model, work / "transient")
    state, fz, power = solver.initial_state(), [], []
    try:
        for k in range(periods * per):
            res, state = solver.step(mesh, state, (k + 1) / (F * per))
            fz.append(res.conductor_force[-1, 0, 1])
            power.append(res.conductor_power[-1, 0])
    finally:
        solver.close()
    f_mean, p_mean = np.mean(fz[-per:]), np.mean(power[-per:])  # rectangle rule on a period: spectral
    print(f"\nF_z mean: transient {f_mean:.5f} N, harmonic {harm.conductor_force[0, 1]:.5f} N; "
          f"P mean {p_mean:.4f} vs {harm.conductor_power[0]:.4f} W")
    assert harm.conductor_force[0, 1] > 0  # the plate is repelled
    assert f_mean == pytest.approx(harm.conductor_force[0, 1], rel=0.01)
    assert p_mean == pytest.approx(harm.conductor_power[0], rel=0.01)


def test_harmonic_needs_prescribed_currents(tmp_path):
    model = EMModel(True, coils=[Coil(5)], circuit=Circuit(1e-4, 1e3))
    with pytest.raises(ValueError, match="not a capacitor-bank circuit"):
        solve_harmonic(model, None, F, [1.0], tmp_path)
