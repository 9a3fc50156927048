"""Step-field diffusion into a conducting half-space (2D planar slab).

Reference: the exact solution of the 1D diffusion equation dH/dt = (1/(mu0 sigma)) d2H/dx2 with
H(0, t) = H0 for t > 0: H(x, t) = H0 erfc(x / (2 sqrt(t / (mu0 sigma)))) (Carslaw & Jaeger), and the
magnetic pressure on the half-space, int J x B dx = B0^2 / (2 mu0) (Ampere: J = -dH/dx, B = mu0 H).
The slab (4 mm) is > 5 diffusion lengths deep at t = 20 us, so the a = 0 end has no effect.
"""
import numpy as np
import pytest
from scipy.special import erfc

from pulseform.solvers.getdp import Conductor, EMModel, GetDPSolver, slab_mesh

from getdp_testlib import needs_getdp

MU0 = 4e-7 * np.pi
SIGMA, H0, T, LENGTH = 3.5e7, 1e5, 20e-6, 4e-3


def diffusion_run(work, h, n_steps):
    mesh = slab_mesh(LENGTH, h)
    solver = GetDPSolver(EMModel(False, conductors=[Conductor(SIGMA)], h0_step=H0), work)
    res, _ = solver.step(mesh, solver.initial_state(), T, n_steps, run_name=f"h{h:g}_n{n_steps}")
    x = mesh.points[mesh.triangles[res.elements]][:, :, 0]
    xa, xb = x.min(axis=1), x.max(axis=1)
    h_num = res.flux_density[-1][:, 1] / MU0          # H_y, constant on each element
    g, w = np.polynomial.legendre.leggauss(5)        # L2 error over each element's x-extent
    xs = 0.5 * (xa + xb)[:, None] + 0.5 * (xb - xa)[:, None] * g
    h_ex = H0 * erfc(xs / (2 * np.sqrt(T / (MU0 * SIGMA))))
    # two triangles per strip cell: each covers the cell's x-range, so divide by 2 * LENGTH
    err = np.sqrt(((h_num[:, None] - h_ex) ** 2 * 0.5 * w * (xb - xa)[:, None]).sum() / (2 * LENGTH)) / H0
    area = np.abs(mesh.areas()[res.elements])
    pressure = (res.force_density[-1][:, 0] * area).sum() / h   # per unit surface (width h)
    return err, pressure


def fitted_rate(steps, errors):
    return np.polyfit(np.log(steps), np.log(errors), 1)[0]


@pytest.mark.slow
@pytest.mark.getdp
@needs_getdp
def test_first_order_in_h_and_magnetic_pressure(work):
    """(Slow, ~8 s: three meshes of 400 steps. The default tier's check of the same diffusion run against the same
    erfc solution: test_first_order_in_dt.)"""
    hs = [0.1e-3, 0.05e-3, 0.025e-3]
    out = [diffusion_run(work, h, 400) for h in hs]     # dt = 0.05 us: time error << space error
    errs = [e for e, _ in out]
    rate = fitted_rate(hs, errs)
    p_ref = MU0 * H0 ** 2 / 2
    p_err = [abs(p / p_ref - 1) for _, p in out]
    print(f"\nH L2 errors vs erfc: {errs}, fitted order in h: {rate:.3f}; pressure rel. errors {p_err}")
    assert 0.9 < rate < 1.2
    assert errs[-1] < 3.5e-3
    assert max(p_err) < 0.01


@pytest.mark.getdp
@needs_getdp
def test_first_order_in_dt(work):
    ns = [4, 8, 16, 32]
    errs = [diffusion_run(work, 0.00625e-3, n)[0] for n in ns]   # fine mesh: space error << time error
    dts = [T / n for n in ns]
    rate = fitted_rate(dts, errs)
    print(f"\nH L2 errors vs erfc: {errs} for dt = {dts}, fitted order in dt: {rate:.3f}")
    assert 0.85 < rate < 1.2
    assert errs[-1] < 2.5e-3
