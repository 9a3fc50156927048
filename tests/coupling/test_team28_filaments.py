"""The filament model on prescribed coil currents (orchestrator/em/filaments.py DrivenFilaments), the
independent model of TEAM Workshop Problem 28 (cases/team28_levitation), against closed forms:

- a ring held on its support over a coil on I0 sin(ωt): once its L/R transient has died, its current
  is the phasor i = −jωM / (R + jωL) I0 (lumped.phasor_ring_current) with M from the section-averaged
  Maxwell formula, L from Rosa's and R = 2πr/(σA) (orchestrator/em/lumped.py), to 1e-3;
- a ring lifted by one period of current falls freely back onto its support, sqrt(2h/g) after its
  apex h, and stays there (the inelastic stop of the case's rigid body), never below it;
- the stored reference curve (cases/team28_levitation/reference/filament_model.csv) settles where the
  cycle-mean force of the frequency-domain solution of the same filaments, ½ Re(Σ_c Ĩ_c conj(∂M_c/∂z · ĩ))
  with (R + jωL_ff) ĩ = −jω Mᵀ Ĩ, carries the plate's weight, to 0.05 mm.
"""
from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from pulseform.orchestrator.em.filaments import DrivenFilaments, filament_grid
from pulseform.orchestrator.em.lumped import (phasor_ring_current, ring_resistance, ring_self_inductance,
                                              section_mutual_inductance)

REPO = Path(__file__).resolve().parents[2]
REF = REPO / "cases/team28_levitation/reference"
COIL = (0.025, -0.005, 0.035, 0.0)
RING = (0.029, 0.002, 0.031, 0.004)
SIGMA, TURNS, I0, F = 3.5e7, 100, 50.0, 50.0


def test_held_ring_current_is_the_phasor_solution():
    w = 2 * math.pi * F
    fm = DrivenFilaments([([COIL], TURNS)], lambda t: np.array([I0 * math.sin(w * t)]), [RING], SIGMA,
                         mass=1.0, gravity=9.81)
    t = np.linspace(0.04, 0.06, 401)  # τ = L/R ≈ 0.1 ms: 400 time constants after the switch-on
    out = fm.solve(0.06, t, rtol=1e-9)
    assert np.all(out["position_m"] == 0.0)  # 1 kg: held on its support
    rc, wc, hc = 0.03, 0.002, 0.002
    m = TURNS * section_mutual_inductance(COIL, RING, n=6)[0]
    h = phasor_ring_current(w, m, ring_resistance(rc, wc, hc, SIGMA), ring_self_inductance(rc, wc, hc))
    exact = np.imag(h * I0 * np.exp(1j * w * t))  # I0 sin(wt) = Im(I0 e^(jwt))
    err = np.abs(out["conductor_current_A"] - exact).max() / np.abs(exact).max()
    print(f"\nring current amplitude {np.abs(exact).max():.3f} A; largest difference {err:.2e} of it")
    assert err < 1e-3


def test_lifted_ring_falls_back_onto_its_support_and_rests():
    """One period of 200 A lifts a 50 g ring; once its current has died (τ ≈ 0.1 ms) it falls freely:
    back on its support sqrt(2 h / g) after its apex h, and at rest there to the end."""
    w = 2 * math.pi * F
    burst = lambda t: np.array([200.0 * math.sin(w * t) if t < 1 / F else 0.0])  # noqa: E731
    fm = DrivenFilaments([([COIL], TURNS)], burst, [RING], SIGMA, mass=0.05, gravity=9.81)
    t = np.linspace(0.0, 0.2, 2001)
    out = fm.solve(0.2, t, rtol=1e-8)
    z = out["position_m"]
    k = int(np.argmax(z))
    landed = t[(z == 0.0) & (t > t[k])][0]
    print(f"\nmax rise {z[k] * 1e3:.3f} mm at {t[k] * 1e3:.1f} ms; on its support from {landed * 1e3:.1f} ms "
          f"(free fall: {(t[k] + math.sqrt(2 * z[k] / 9.81)) * 1e3:.1f} ms)")
    assert z[k] > 1e-3 and t[k] > 1 / F and np.all(z >= 0.0)
    assert landed == pytest.approx(t[k] + math.sqrt(2 * z[k] / 9.81), abs=2e-4)  # the 0.1 ms samples
    assert np.all(z[t >= landed] == 0.0) and np.all(out["velocity_m_s"][t >= landed] == 0.0)


def _team28_filaments() -> tuple[DrivenFilaments, dict, float]:
    spec = tomllib.loads((REF / "team28_spec.toml").read_text())
    p = spec["plate"]
    plate = (0.0, p["start_height"], p["radius"], p["start_height"] + p["thickness"])
    fm = DrivenFilaments([([tuple(c["winding"])], c["turns"]) for c in spec["coils"]], lambda t: np.zeros(2),
                         filament_grid(plate, 43, 2), p["conductivity"], p["mass"], gravity=9.81, z_max=0.025,
                         coil_cell=8e-3)  # the reference's 4 mm cells: the same coupling to 1e-5, 4 x the time
    return fm, spec, p["start_height"]


def test_reference_settles_at_the_frequency_domain_equilibrium():
    fm, spec, start = _team28_filaments()
    w = 2 * math.pi * spec["frequency"]
    coil = np.array([c["sign"] for c in spec["coils"]], float) * spec["current_amplitude"]

    def mean_force(z: float) -> float:
        m, dm = fm.coupling(z)
        i = np.linalg.solve(np.diag(fm.r_f) + 1j * w * fm.l_ff, -1j * w * (coil @ m))
        return 0.5 * float(np.real(coil @ np.conj(dm @ i)))

    weight = fm.mass * fm.gravity
    z_eq = brentq(lambda z: mean_force(z) - weight, 0.0, 0.02, xtol=1e-9)
    ref = np.genfromtxt(REF / "filament_model.csv", delimiter=",", names=True, skip_header=4)
    settled = float(np.mean(ref["height_mm"][ref["time_ms"] >= 1200.0]))
    print(f"\nequilibrium {(start + z_eq) * 1e3:.4f} mm; reference curve's mean from 1.2 s {settled:.4f} mm "
          f"(measured 11.32 mm)")
    assert mean_force(0.0) > weight  # it lifts
    assert settled == pytest.approx((start + z_eq) * 1e3, abs=0.05)
