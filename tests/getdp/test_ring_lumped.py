"""A fixed thin ring above a coil with a 50 Hz sinusoidal current: GetDP's transient solution against
the lumped R-L model of the ring (issue 17's lumped-circuit check, at the solver level).

Reference (orchestrator/em/lumped.py, independent of GetDP): the ring is one R-L loop, driven by
-d(M i_coil)/dt with the mutual inductance M of the coil's and the ring's sections (Maxwell's
elliptic-integral formula averaged over both sections), R = 2 pi r / (sigma A), L from Rosa's
formula; the axial force is i_coil i_ring dM/dz. Valid when the skin depth (aluminium at 50 Hz:
12 mm) is several times the ring's section (3 mm) and the ring is thin (3 mm at r = 41.5 mm).
Both start from rest with i_coil = N I0 sin(w t), so the whole history is compared: force and ring
Joule power (R i_ring^2), over 1.25 periods (the ring's L/R = 0.2 ms transient included).
Measured (1040 nodes): peak force 2.0165 N vs 2.0192 N lumped, force history within 0.66 % of the
peak, power 0.66 %; the history difference is implicit Euler's first-order time error (1.67 % with
400 steps, 0.66 % with 1000: extrapolated to dt -> 0 it vanishes).
"""
import math

import numpy as np
import pytest

from pulseform.orchestrator.em.lumped import (RingCircuit, ring_resistance, ring_self_inductance,
                                              section_mutual_inductance)
from pulseform.solvers.getdp import Coil, Conductor, DampedSine, EMModel, GetDPSolver, Rect, coil_conductor_mesh

from getdp_testlib import needs_getdp

SIGMA_AL = 3.5e7
F, N_TURNS, I0 = 50.0, 100, 50.0  # 5 kA-turns
COIL = (0.040, -0.002, 0.044, 0.002)  # (r0, z0, r1, z1), m
RING = (0.040, 0.0085, 0.043, 0.0115)


@pytest.mark.slow
@pytest.mark.getdp
@needs_getdp
def test_fixed_ring_follows_the_lumped_rl_model(work):
    """(Slow, ~18 s: 1000 steps on a 0.25 m domain. The default tier's comparison with the same lumped model
    (orchestrator/em/lumped.py) on GetDP: tests/coupling/test_jumping_ring.py::test_released_ring_follows_the_lumped_ode.)"""
    w = 2 * math.pi * F
    mesh = coil_conductor_mesh([[Rect(*COIL)]], [Rect(*RING)], r_domain=0.25, r_shell=0.3125, h_fine=1e-3,
                               h_coarse=2.5e-2, h_conductor=5e-4)
    model = EMModel(True, coils=[Coil(N_TURNS, waveform=DampedSine(I0, 0.0, w))],
                    conductors=[Conductor(SIGMA_AL)], shell=(0.25, 0.3125))
    t_end, n = 1.25 / F, 1000
    res, _ = GetDPSolver(model, work).step(mesh, GetDPSolver(model, work).initial_state(), t_end, n)
    t = np.asarray(res.times)
    fz = res.conductor_force[:, 0, 1]
    power = res.conductor_power[:, 0]

    rc, wc, hc = 0.5 * (RING[0] + RING[2]), RING[2] - RING[0], RING[3] - RING[1]
    R, L = ring_resistance(rc, wc, hc, SIGMA_AL), ring_self_inductance(rc, wc, hc)
    M, dM = section_mutual_inductance(COIL, RING)
    z = 0.5 * (RING[1] + RING[3]) - 0.5 * (COIL[1] + COIL[3])
    ring = RingCircuit(0.5 * (COIL[0] + COIL[2]), rc, R, L, coupling=lambda _z: (M, dM))  # fixed ring
    coil = lambda s: (N_TURNS * I0 * math.sin(w * s), N_TURNS * I0 * w * math.cos(w * s))  # noqa: E731
    sol = ring.solve(coil, t[-1], z, t_eval=t)
    i_ring = sol.y[2]
    f_ref = ring.force(z, np.array([coil(s)[0] for s in t]), i_ring)
    p_ref = R * i_ring ** 2

    peak = np.abs(f_ref).max()
    err_f = np.abs(fz - f_ref).max() / peak
    # the force repeats every half period: its peak within one such window [T/2, T] gives the phase
    win = np.flatnonzero((t >= 0.5 / F) & (t <= 1.0 / F))
    k_fe, k_ref = win[np.argmax(np.abs(fz[win]))], win[np.argmax(np.abs(f_ref[win]))]
    print(f"\n{mesh.n_nodes} nodes; lumped: R {R:.3e} Ohm, L {L:.3e} H, wL/R {w * L / R:.3f}, M {M:.3e} H, "
          f"dM/dz {dM:.3e} H/m; peak |F_z| FE {np.abs(fz).max():.4e} N vs lumped {peak:.4e} N, "
          f"max |F - F_ref| / peak {err_f:.2e}; peak times {t[k_fe] * 1e3:.3f} vs {t[k_ref] * 1e3:.3f} ms; "
          f"peak power FE {power.max():.4e} W vs {p_ref.max():.4e} W")
    assert np.abs(fz).max() == pytest.approx(peak, rel=0.02)
    assert err_f < 0.02  # force history, phase included
    assert abs(t[k_fe] - t[k_ref]) < 0.02 / F  # the peak within 2 % of a period
    assert math.sqrt(power.max()) == pytest.approx(math.sqrt(p_ref.max()), rel=0.02)  # ring current amplitude
