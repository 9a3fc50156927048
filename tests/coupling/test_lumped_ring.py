"""The lumped-circuit reference of the ring checks (orchestrator/em/lumped.py), each formula against
an independent computation: Maxwell's mutual inductance against Neumann's double line integral
(numerical quadrature), its z-derivative against a central difference, the far-field dipole limit,
the rectangle's geometric mean distance against a direct numerical average of ln|r1 - r2|, the
ring's time integration against the phasor (steady-state) solution, and free fall."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from pulseform.orchestrator.em.lumped import (MU0, RingCircuit, mutual_inductance, mutual_inductance_gradient,
                                              phasor_ring_current, ring_resistance, ring_self_inductance)


def _neumann(a: float, b: float, z: float) -> float:
    """M = mu0 a b / 2 * int_0^2pi cos(phi) / sqrt(a^2 + b^2 + z^2 - 2 a b cos(phi)) dphi (Neumann)."""
    f = lambda p: math.cos(p) / math.sqrt(a * a + b * b + z * z - 2 * a * b * math.cos(p))  # noqa: E731
    val, _ = quad(f, 0.0, math.pi, epsabs=0.0, epsrel=1e-13, limit=400)
    return MU0 * a * b * val  # the integrand is even about pi: twice the half range, times 1/2


@pytest.mark.parametrize("a,b,z", [(0.05, 0.04, 0.0), (0.05, 0.04, 0.01), (0.03, 0.08, 0.05), (0.05, 0.05, 0.002)])
def test_mutual_inductance_equals_neumann_integral(a, b, z):
    assert mutual_inductance(a, b, z) == pytest.approx(_neumann(a, b, z), rel=1e-10)


@pytest.mark.parametrize("z", [-0.02, -0.003, 0.0, 0.001, 0.01, 0.04])
def test_gradient_equals_central_difference(z):
    a, b, h = 0.05, 0.04, 1e-6
    fd = (mutual_inductance(a, b, z + h) - mutual_inductance(a, b, z - h)) / (2 * h)
    got = mutual_inductance_gradient(a, b, z)
    assert got == pytest.approx(fd, rel=1e-6, abs=1e-12 * MU0)
    if z > 0:
        assert got < 0  # same-sense currents attract: M falls with distance


def test_far_field_is_the_dipole_limit():
    """M -> mu0 pi a^2 b^2 / (2 z^3) for z >> a, b (two magnetic dipoles on one axis)."""
    a, b, z = 0.01, 0.02, 4.0
    assert mutual_inductance(a, b, z) == pytest.approx(MU0 * math.pi * a * a * b * b / (2 * z ** 3), rel=1e-4)


@pytest.mark.parametrize("w,h", [(2e-3, 2e-3), (4e-3, 1e-3)])
def test_rosa_gmd_of_the_section(w, h):
    """The self-inductance uses g = 0.2235 (w + h); the geometric mean distance of the rectangle,
    ln g = <ln |r1 - r2|> over pairs of points, computed here by Monte Carlo (2e6 pairs, standard
    error of ln g ~ 6e-4), agrees to 0.5 %; and L equals the mutual inductance of two loops g apart
    to O((g/R)^2)."""
    rng = np.random.default_rng(7)
    n = 2_000_000
    p = rng.random((n, 4)) * np.array([w, h, w, h])
    lg = np.mean(0.5 * np.log((p[:, 0] - p[:, 2]) ** 2 + (p[:, 1] - p[:, 3]) ** 2))
    g = 0.2235 * (w + h)
    assert math.exp(lg) == pytest.approx(g, rel=5e-3)
    r = 0.05
    assert ring_self_inductance(r, w, h) == pytest.approx(mutual_inductance(r, r, g), rel=(g / r) ** 2)


def test_ring_resistance_and_bad_sections():
    assert ring_resistance(0.05, 2e-3, 1e-3, 3.5e7) == pytest.approx(2 * math.pi * 0.05 / (3.5e7 * 2e-6))
    with pytest.raises(ValueError, match="must be > 0"):
        ring_self_inductance(0.05, 0.0, 1e-3)


def test_fixed_ring_reaches_the_phasor_solution():
    """A fixed ring under i_coil = I0 sin(w t): after the transient (20 L/R), the integrated ring current
    equals Re(I_ring e^{jwt}) with I_ring = -j w M / (R + j w L) I0 (to 1e-6 of its amplitude), and the
    cycle-mean force equals (1/2) Re(I_coil conj(I_ring)) dM/dz."""
    a, r, z0, f, i0 = 0.04, 0.035, 0.01, 200.0, 1000.0
    w = 2 * math.pi * f
    R, L = ring_resistance(r, 3e-3, 3e-3, 3.5e7), ring_self_inductance(r, 3e-3, 3e-3)
    ring = RingCircuit(a, r, R, L)
    tau = L / R
    t1 = (math.ceil(20 * tau * f) + 2) / f
    t = np.linspace(t1 - 1 / f, t1, 401)
    sol = ring.solve(lambda s: (i0 * math.sin(w * s), i0 * w * math.cos(w * s)), t1, z0, t_eval=t)
    M = mutual_inductance(a, r, z0)
    ph = phasor_ring_current(w, M, R, L) * i0
    want = (ph * np.exp(1j * (w * t - math.pi / 2))).real  # sin(wt) = Re(e^{j(wt - pi/2)})
    assert np.max(np.abs(sol.y[2] - want)) < 1e-6 * abs(ph)
    force = ring.force(z0, i0 * np.sin(w * t), sol.y[2])
    mean = np.trapz(force, t) * f
    # i_coil = Re(-j I0 e^{jwt}), i_ring = Re(-j ph e^{jwt}): mean of the product (1/2) Re(I0 conj(ph))
    assert mean == pytest.approx(0.5 * (i0 * np.conj(ph)).real * mutual_inductance_gradient(a, r, z0), rel=1e-5)
    assert mean > 0  # the induced current opposes the coil's: the ring is repelled (lifted)


def test_released_ring_without_current_falls_freely():
    ring = RingCircuit(0.04, 0.035, 1e-4, 1e-7, mass=0.01, gravity=9.81)
    t = np.linspace(0.0, 0.2, 11)
    sol = ring.solve(lambda s: (0.0, 0.0), 0.2, 0.01, w0=1.0, t_eval=t)
    assert np.allclose(sol.y[0], 0.01 + t - 0.5 * 9.81 * t ** 2, rtol=0, atol=1e-9)
