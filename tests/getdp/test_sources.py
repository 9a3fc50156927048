"""Coil sources of the deck (Lib_PulsedForming.pro, waveform 0): I0 e^(-beta (t - t_on))
sin(omega (t - t_on) + phase) from the switch-on time t_on, 0 before, and a direct current (omega 0,
phase pi/2). Reference: the formula evaluated in Python (DampedSine.__call__); GetDP's reported coil
currents must equal it to round-off at every sub-step, also with BDF2 steps; and a coil's field is
proportional to its current (the static field of a DC coil is constant in time)."""
import math

import numpy as np
import pytest

from pulseform.solvers.getdp import Coil, DampedSine, EMModel, GetDPSolver, Rect, coil_conductor_mesh

from getdp_testlib import needs_getdp

A = [Rect(0.010, -0.002, 0.013, 0.002)]
B = [Rect(0.020, -0.002, 0.023, 0.002)]
WAVES = (DampedSine(2e3, 2e3, 2 * math.pi * 5e3, phase=0.7, t_on=1.5e-4),  # a phased sine switched on later
         DampedSine(-500.0, 0.0, 0.0, phase=0.5 * math.pi))                # a direct current, negative


def _run(work, scheme: str, n: int):
    mesh = coil_conductor_mesh([A, B], [], r_domain=0.08, r_shell=0.1, h_fine=2e-3, h_coarse=1e-2)
    model = EMModel(True, coils=[Coil(10, waveform=WAVES[0]), Coil(4, waveform=WAVES[1])], shell=(0.08, 0.1),
                    probes=[(0.005, 0.0)])
    solver = GetDPSolver(model, work, time_scheme=scheme)
    state, out = solver.initial_state(), []
    for k in range(n):
        res, state = solver.step(mesh, state, (k + 1) * 2.5e-5, 1 if scheme == "bdf2" else 4)
        out.append((np.asarray(res.times), np.asarray(res.coil_current), np.asarray(res.probe_b)))
    return [np.concatenate(c) for c in zip(*out)]


@pytest.mark.getdp
@needs_getdp
@pytest.mark.parametrize("scheme", ["euler", "bdf2"])
def test_phased_switched_sine_and_dc_currents(work, scheme):
    t, current, b = _run(work, scheme, 12)
    for k, wave in enumerate(WAVES):
        want = wave(t)
        assert np.abs(current[:, k] - want).max() <= 1e-12 * np.abs(want).max(), k
    before = t < WAVES[0].t_on
    assert before.any() and np.all(current[before, 0] == 0.0) and np.all(current[~before, 0] != 0.0)
    # before the switch-on only the DC coil acts: a static field, the same at every sub-step
    bz = b[before, 0, 1]
    assert np.abs(bz - bz[0]).max() <= 1e-9 * abs(bz[0]) and abs(bz[0]) > 0
