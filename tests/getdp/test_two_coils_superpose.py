"""Two coaxial coils with opposite currents over an aluminium plate: the transient field of both
equals the sum of each coil's field alone (eddy currents included: the A-V problem is linear), to
1e-9 of its largest value, at probe points in the air, the plate and between the coils; and the
plate's induced current of both (its Joule power is quadratic: the cross term) is the power of the
summed fields, i.e. P(A+B) = P(A) + P(B) + 2 P_cross with P_cross bounded by sqrt(P(A) P(B)).
Issue 17's linear check of several coils on their own sources, at the solver level."""
import numpy as np
import pytest

from pulseform.solvers.getdp import Coil, Conductor, DampedSine, EMModel, GetDPSolver, Rect, coil_conductor_mesh

from getdp_testlib import needs_getdp

COIL_A = [Rect(0.010 + i * 0.004, -0.003, 0.013 + i * 0.004, -0.001) for i in range(3)]
COIL_B = [Rect(0.030 + i * 0.004, -0.003, 0.033 + i * 0.004, -0.001) for i in range(2)]
PLATE = Rect(0.0, 0.0, 0.05, 0.002)
PROBES = [(0.005, 0.001), (0.025, 0.001), (0.02, -0.002), (0.04, 0.01), (0.015, -0.02)]


def _probe_b(work, amp_a: float, amp_b: float) -> np.ndarray:
    mesh = coil_conductor_mesh([COIL_A, COIL_B], [PLATE], r_domain=0.15, r_shell=0.1875, h_fine=1.5e-3,
                               h_coarse=2.5e-2, h_conductor=1e-3)
    model = EMModel(True, coils=[Coil(3, waveform=DampedSine(amp_a, 5e3, 6e4)),
                                 Coil(2, waveform=DampedSine(amp_b, 5e3, 6e4))],
                    conductors=[Conductor(3.5e7)], shell=(0.15, 0.1875), probes=PROBES)
    solver = GetDPSolver(model, work)
    res, _ = solver.step(mesh, solver.initial_state(), 60e-6, 30)
    return np.asarray(res.probe_b), np.asarray(res.conductor_power[:, 0])


@pytest.mark.getdp
@needs_getdp
def test_two_coils_with_opposite_currents_superpose(tmp_path):
    both, p_ab = _probe_b(tmp_path / "ab", 8e3, -12e3)
    a, p_a = _probe_b(tmp_path / "a", 8e3, 0.0)
    b, p_b = _probe_b(tmp_path / "b", 0.0, -12e3)
    scale = np.abs(both).max()
    err = np.abs(both - (a + b)).max() / scale
    print(f"\nmax |B(A+B) - B(A) - B(B)| / max|B| = {err:.2e} over {both.shape[0]} steps x {both.shape[1]} probes")
    assert np.abs(a).max() > 0.05 * scale and np.abs(b).max() > 0.05 * scale  # both coils matter
    assert err < 1e-9
    cross = 0.5 * (p_ab - p_a - p_b)
    assert np.all(np.abs(cross) <= np.sqrt(p_a * p_b) * (1 + 1e-9) + 1e-12 * p_ab.max())
    assert np.abs(cross).max() > 1e-3 * p_ab.max()  # the fields do interact in the plate
