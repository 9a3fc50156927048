"""2D planar model, two coils with their own currents, VolSphShell open boundary.

Reference: the 2D Biot-Savart law B = mu0/(2 pi) int J e_z x (x - x') / |x - x'|^2 dA' over the
two square conductor cross-sections (8 x 8 Gauss points), a go-and-return pair (net current 0,
so the field decays like 1/r^2 and the shell transformation to infinity is well posed).
"""
import numpy as np
import pytest

from pulseform.solvers.getdp import Coil, CurrentTable, DampedSine, EMModel, GetDPSolver, Rect, coil_conductor_mesh

from getdp_testlib import needs_getdp

MU0 = 4e-7 * np.pi
I0 = 5e3
SQUARES = [Rect(-0.012, -0.002, -0.008, 0.002), Rect(0.008, -0.002, 0.012, 0.002)]


def planar_biot_savart(rects, currents, x, y, n_gauss=8):
    g, w = np.polynomial.legendre.leggauss(n_gauss)
    b = np.zeros(2)
    for r, cur in zip(rects, currents):
        area = (r.x1 - r.x0) * (r.y1 - r.y0)
        for gi, wi in zip(g, w):
            for gj, wj in zip(g, w):
                xs = 0.5 * (r.x0 + r.x1) + 0.5 * (r.x1 - r.x0) * gi
                ys = 0.5 * (r.y0 + r.y1) + 0.5 * (r.y1 - r.y0) * gj
                dx, dy = x - xs, y - ys
                b += MU0 / (2 * np.pi) * cur / area * wi * wj * area / 4 * np.array([-dy, dx]) / (dx * dx + dy * dy)
    return b


@pytest.mark.getdp
@needs_getdp
def test_go_and_return_pair_vs_biot_savart(work):
    mesh = coil_conductor_mesh([[SQUARES[0]], [SQUARES[1]]], [], axisymmetric=False, r_domain=0.06, r_shell=0.075,
                               h_fine=5e-4, h_coarse=4e-3)
    probes = [(0.0, 0.0), (0.0, 0.01), (0.02, 0.0)]
    model = EMModel(False, coils=[Coil(1, waveform=CurrentTable([0, 1], [I0, I0])),
                                  Coil(3, waveform=CurrentTable([0, 1], [-I0 / 3, -I0 / 3]))],
                    shell=(0.06, 0.075), probes=probes)
    solver = GetDPSolver(model, work)
    res, _ = solver.step(mesh, solver.initial_state(), 1e-6, 1)
    np.testing.assert_allclose(res.coil_current[-1], [I0, -I0 / 3])
    b = res.probe_b[-1]
    ref = np.array([planar_biot_savart(SQUARES, [I0, -I0], x, y) for x, y in probes])
    err = np.linalg.norm(b - ref, axis=1) / np.linalg.norm(ref, axis=1)
    print(f"\nplanar pair ({mesh.n_nodes} nodes): |B - B_ref| / |B_ref| at {probes}: {err}")
    # the centre is a symmetry point; elsewhere a point value of the element-wise constant B of
    # P1 elements is only first-order accurate (2-10 % on this coarse mesh), so only printed
    assert err[0] < 0.01
    # the two conductors repel (opposite currents): coil 1 pushed to -x, coil 2 to +x, equal and opposite
    f1, f2 = res.coil_force[-1]
    assert f1[0] < 0 < f2[0]
    assert abs(f1[0] + f2[0]) < 0.01 * abs(f1[0])
    # reference: int_{square 2} J2 e_z x B_1 dA, B_1 from square 1 by the same Biot-Savart quadrature
    r2, g, wg = SQUARES[1], *np.polynomial.legendre.leggauss(6)
    area = (r2.x1 - r2.x0) * (r2.y1 - r2.y0)
    f_ref = 0.0
    for gi, wi in zip(g, wg):
        for gj, wj in zip(g, wg):
            x = 0.5 * (r2.x0 + r2.x1) + 0.5 * (r2.x1 - r2.x0) * gi
            y = 0.5 * (r2.y0 + r2.y1) + 0.5 * (r2.y1 - r2.y0) * gj
            b1 = planar_biot_savart(SQUARES[:1], [I0], x, y)
            f_ref += (-I0 / area) * (-b1[1]) * wi * wj * area / 4
    print(f"force per metre {f2[0]:.2f} N/m, Biot-Savart {f_ref:.2f} N/m ({f2[0] / f_ref - 1:+.3%}); "
          f"filaments {MU0 * I0 ** 2 / (2 * np.pi * 0.02):.2f} N/m")
    assert f2[0] == pytest.approx(f_ref, rel=0.01)
