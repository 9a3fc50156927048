"""The filament model of the actuator reference (orchestrator/em/filaments.py) against closed forms:
with a conductor of negligible conductivity the coil current is the series R-L-C discharge
I(t) = V0 / (ω_d L) e^(−αt) sin(ω_d t), α = R / 2L, ω_d = sqrt(1/LC − α²) (L = coil + leads, R = coil
+ leads); with a conducting disk the disk's momentum equals the impulse of the force, and the
inductance matrix of flat filaments is refused (indefinite)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pulseform.orchestrator.em.filaments import FilamentActuator, _mutual_matrix, filament_grid

TURNS = [(0.010 + 0.005 * k, -0.003, 0.014 + 0.005 * k, 0.0) for k in range(3)]
DISK = (0.0, 1e-3, 0.03, 3e-3)


def test_coil_current_is_the_rlc_discharge_without_eddy_currents():
    fa = FilamentActuator(TURNS, filament_grid(DISK, 15, 1), 1e-6, 100e-6, 2e3, 0.01, 1e-6, mass=0.02, gravity=9.81)
    L, R = fa.l_coil, fa.r_coil
    a = R / (2 * L)
    wd = math.sqrt(1 / (L * 100e-6) - a * a)
    t = np.linspace(0.0, 2e-4, 201)
    out = fa.solve(2e-4, t, rtol=1e-10)
    exact = 2e3 / (wd * L) * np.exp(-a * t) * np.sin(wd * t)
    assert np.abs(out["coil_current_A"] - exact).max() < 1e-6 * np.abs(exact).max()
    assert np.abs(out["position_m"]).max() == 0.0  # its weight keeps it on its support


def test_disk_momentum_is_the_force_impulse():
    fa = FilamentActuator(TURNS, filament_grid(DISK, 15, 1), 3.5e7, 100e-6, 2e3, 0.01, 1e-6, mass=0.02)
    t = np.linspace(0.0, 1e-4, 2001)
    out = fa.solve(1e-4, t, rtol=1e-9)
    impulse = np.trapz(out["force_N"], t)
    assert out["velocity_m_s"][-1] > 1.0
    assert 0.02 * out["velocity_m_s"][-1] == pytest.approx(impulse, rel=1e-4)  # the trapezoid rule's error


def test_flat_filaments_are_refused():
    with pytest.raises(ValueError, match="square"):
        _mutual_matrix(filament_grid((0.0, 1e-3, 0.04, 3e-3), 20, 4))
