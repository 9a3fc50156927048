"""A coil's orientation (``Coil.sign``, the deck's ``Coil_Sign~{k}``) on a capacitor bank and on a
prescribed source. Two identical coaxial coils, mirror images about z = 0, in air (no eddy currents: the
field is an instantaneous linear function of the coil currents on a fixed mesh), in series on one bank.

References, all from the same mesh (so the comparisons hold to round-off, not to the discretisation):
- static runs with 1 A DC in coil A alone, in B alone and in both give the per-ampere probe fields b_A,
  b_B and the inductances from the magnetic energy W = ½ Iᵀ L I: L_A = 2 W_A, L_B = 2 W_B,
  M = W_AB − W_A − W_B;
- on the bank with B reversed, B's current is minus the circuit's (the deck connects it the other way
  round), the probe field is I(t) (b_A − b_B), and W(t) = ½ (L_A + L_B − 2 M) I(t)²; with both coils
  forwards ½ (L_A + L_B + 2 M) I(t)² — so a sign that did not reach the circuit fails the energy check.
(B on the symmetry plane is not used: the P1 potential gives a piecewise-constant B whose error near
the windings, ~5 % at 1 mm elements, swamps the B_z that should cancel there.)"""
import math

import numpy as np
import pytest

from pulseform.solvers.getdp import Circuit, Coil, DampedSine, EMModel, GetDPSolver, Rect, coil_conductor_mesh

from getdp_testlib import needs_getdp

A = [Rect(0.010, -0.006, 0.013, -0.002)]
B = [Rect(0.010, 0.002, 0.013, 0.006)]
PROBES = [(0.004, 0.0), (0.0115, 0.0), (0.02, 0.0), (0.008, -0.004), (0.016, 0.01)]
DC = DampedSine(1.0, 0.0, 0.0, phase=0.5 * math.pi)  # 1 A direct current
OFF = DampedSine(0.0, 0.0, 0.0, phase=0.5 * math.pi)


def _mesh():
    return coil_conductor_mesh([A, B], [], r_domain=0.08, r_shell=0.1, h_fine=1e-3, h_coarse=1e-2)


def _static(work, wave_a, wave_b, signs=(1, 1)):
    model = EMModel(True, coils=[Coil(5, waveform=wave_a, sign=signs[0]), Coil(5, waveform=wave_b, sign=signs[1])],
                    shell=(0.08, 0.1), probes=PROBES)
    solver = GetDPSolver(model, work)
    res, _ = solver.step(_mesh(), solver.initial_state(), 1e-6, 1)
    return np.asarray(res.probe_b[-1]), float(res.magnetic_energy[-1]), np.asarray(res.coil_current[-1])


def _bank(work, signs):
    model = EMModel(True, coils=[Coil(5, sign=signs[0]), Coil(5, sign=signs[1])], shell=(0.08, 0.1), probes=PROBES,
                    circuit=Circuit(C=20e-6, V0=2e3, R_ext=5e-3, L_ext=1e-7))
    solver = GetDPSolver(model, work)
    state, rows = solver.initial_state(), []
    for k in range(4):
        res, state = solver.step(_mesh(), state, (k + 1) * 2e-6, 2)
        rows.append((res.circuit_current, res.coil_current, res.probe_b, res.magnetic_energy))
    return [np.concatenate(c) for c in zip(*rows)]


@pytest.mark.getdp
@needs_getdp
def test_reversed_coil_in_series_on_a_bank(tmp_path):
    b_a, w_a, _ = _static(tmp_path / "a", DC, OFF)
    b_b, w_b, _ = _static(tmp_path / "b", OFF, DC)
    _, w_ab, _ = _static(tmp_path / "ab", DC, DC)
    l_a, l_b, m = 2 * w_a, 2 * w_b, w_ab - w_a - w_b
    assert abs(l_a - l_b) < 0.01 * l_a and m > 0.1 * l_a  # mirror images, strongly coupled: the sign matters
    for signs, l_tot in (((1, -1), l_a + l_b - 2 * m), ((1, 1), l_a + l_b + 2 * m)):
        i_cir, i_coil, probe_b, w = _bank(tmp_path / f"bank{signs[1]}", signs)
        scale = np.abs(i_cir).max()
        assert scale > 100.0
        assert np.abs(i_coil[:, 0] - i_cir).max() <= 1e-12 * scale
        assert np.abs(i_coil[:, 1] - signs[1] * i_cir).max() <= 1e-12 * scale
        want_b = i_cir[:, None, None] * (b_a + signs[1] * b_b)[None]
        err_b = np.abs(probe_b - want_b).max() / np.abs(want_b).max()
        err_w = np.abs(w - 0.5 * l_tot * i_cir ** 2).max() / w.max()
        print(f"\nsigns {signs}: L = {l_tot * 1e9:.2f} nH (L_A {l_a * 1e9:.2f}, M {m * 1e9:.2f}); "
              f"probe B vs I (b_A {signs[1]:+d} b_B) {err_b:.1e}, W vs L I^2/2 {err_w:.1e}")
        assert err_b < 1e-9 and err_w < 1e-9


@pytest.mark.getdp
@needs_getdp
def test_reversed_prescribed_coil_carries_minus_its_waveform(tmp_path):
    wave = DampedSine(3e3, 2e3, 2 * math.pi * 5e3, phase=0.3)
    b_fwd, _, i_fwd = _static(tmp_path / "fwd", wave, OFF)
    b_rev, _, i_rev = _static(tmp_path / "rev", wave, OFF, signs=(-1, 1))
    assert i_fwd[0] == pytest.approx(float(wave(1e-6)), rel=1e-12) and i_rev[0] == -i_fwd[0]
    assert np.abs(b_rev + b_fwd).max() <= 1e-12 * np.abs(b_fwd).max()
