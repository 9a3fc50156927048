"""Coil over a disk: the total Lorentz force integral equals the sum of per-element f V.

Reference: consistency of two independent outputs -- GetDP's Gauss-integrated total force
(7-point rule, 2 pi r included) and the per-element force density j x B evaluated at the element
centroid times the element volume 2 pi r_c A.  Also checked: the element-averaged densities
(what the coupling receives) add up to the totals to round-off.  Setup like SOLVER_NOTES's
(5-turn coil, 20 kA e^(-1e4 t) sin(1e5 t), 1 mm Al disk of radius 60 mm 1 mm above; turn sections
3 mm x 2 mm chosen here).
"""
import numpy as np
import pytest

from pulseform.solvers.getdp import Coil, Conductor, DampedSine, EMModel, GetDPSolver, Rect, coil_conductor_mesh

from getdp_testlib import needs_getdp


def coil_disk_model():
    turns = [Rect(0.010 + i * 0.004, -0.003, 0.013 + i * 0.004, -0.001) for i in range(5)]
    disk = Rect(0.0, 0.0, 0.06, 0.001)
    mesh = coil_conductor_mesh([turns], [disk], r_domain=0.15, r_shell=0.1875, h_fine=1e-3, h_coarse=2e-2,
                               h_conductor=5e-4)
    model = EMModel(True, coils=[Coil(5, waveform=DampedSine(20e3, 1e4, 1e5))], conductors=[Conductor(3.5e7)],
                    shell=(0.15, 0.1875))
    return mesh, model


@pytest.mark.getdp
@needs_getdp
def test_force_integral_equals_sum_of_element_forces(work):
    mesh, model = coil_disk_model()
    solver = GetDPSolver(model, work)
    res, _ = solver.step(mesh, solver.initial_state(), 20e-6, 40)
    vol = mesh.volumes(axisymmetric=True)[res.elements]
    summed = np.einsum("sek,e->sk", res.force_density_centroid, vol)   # centroid f times volume
    integral = res.conductor_force[:, 0, :]
    fz = integral[:, 1]
    rel = np.abs(summed[:, 1] - fz) / np.abs(fz).max()
    print(f"\n{mesh.n_nodes} nodes: peak F_z {fz.max():.1f} N; max |sum f V - integral| / max|F_z| = {rel.max():.2e}")
    assert fz.max() > 0                      # repulsion: the disk above the coil is pushed up (+z)
    assert rel.max() < 1e-3
    assert np.all(res.element_tags == 201)
    assert len(res.elements) == np.count_nonzero(mesh.tri_tags == 201)
    # element-averaged densities (what the coupling uses) add up to the totals to round-off
    f_avg = np.einsum("sek,e->sk", res.force_density, vol)
    assert np.abs(f_avg - integral).max() < 1e-9 * np.abs(fz).max()
    p_sum = res.joule_density @ vol
    assert np.abs(p_sum - res.conductor_power[:, 0]).max() < 1e-9 * res.conductor_power[:, 0].max()
