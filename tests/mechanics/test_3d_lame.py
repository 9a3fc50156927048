"""Elastic thick cylinder (Lamé) on a 3D sector (issue 20): a quarter of a tube (a = 0.1 m,
b = 0.2 m, 0 <= theta <= 90 deg, height 0.02 m) in linear tetrahedra, roller conditions on the
symmetry planes x = 0 and y = 0 and on both ends z = 0, z = H (plane strain), a slowly ramped
internal follower pressure — the 3D counterpart of tests/mechanics/test_lame.py.

Reference: Lamé's solution (e.g. Timoshenko & Goodier, Theory of Elasticity, sec. 33):
sigma_r = A - B/r^2, sigma_theta = A + B/r^2, A = p a^2/(b^2 - a^2), B = p a^2 b^2/(b^2 - a^2),
u = (1 + nu)/E ((1 - 2 nu) A r + B / r) in plane strain. Tolerance 1 % (the issue's), 3 % for the
small radial stress at mid-wall (as in 2D)."""
import math

import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import BodySpec, ExplicitSolver3D, Material

MAT = Material(2800.0, 26.5e9, 65.1e9, 1e12, 0.0)    # elastic (yield far away)
A_IN, B_OUT, H = 0.1, 0.2, 0.02
P0 = 100e6


def quarter_tube(nr=10, nth=24, nz=2):
    """Tetrahedra of a box in (r, theta, z) mapped to x = r cos theta, y = r sin theta."""
    msh = dmesh.create_box(MPI.COMM_SELF, [np.array([A_IN, 0.0, 0.0]),
                                           np.array([B_OUT, 0.5 * math.pi, H])],
                           [nr, nth, nz], dmesh.CellType.tetrahedron)
    g = msh.geometry.x
    r, th = g[:, 0].copy(), g[:, 1].copy()
    g[:, 0] = r * np.cos(th)
    g[:, 1] = r * np.sin(th)
    g[np.isclose(th, 0.5 * math.pi), 0] = 0.0     # exactly on the symmetry plane x = 0
    return msh


def test_thick_cylinder_lame_3d_sector():
    tol = 1e-9
    fixed = ((lambda x: np.abs(x[0]) < tol, (0,)), (lambda x: np.abs(x[1]) < tol, (1,)),
             (lambda x: np.isclose(x[2], 0.0) | np.isclose(x[2], H), (2,)))
    s = ExplicitSolver3D([BodySpec("tube", quarter_tube(), MAT, initial_velocity=(0, 0, 0),
                                   fixed=fixed)], comm=MPI.COMM_SELF)
    b = s.bodies["tube"]
    inner = lambda x: x[0] ** 2 + x[1] ** 2 < (A_IN + 1e-3) ** 2  # noqa: E731 (current config)
    t_ramp, t_hold = 2.0e-3, 0.4e-3
    dt = 0.9 * s.stable_time_step()
    n_block = 10
    R0 = np.hypot(b.X0[:, 0], b.X0[:, 1])
    ia = np.flatnonzero(np.isclose(R0, A_IN))
    ib = np.flatnonzero(np.isclose(R0, B_OUT))
    ur_a, ur_b = [], []
    while s.time < t_ramp + t_hold:
        tm = s.time + 0.5 * n_block * dt
        p = P0 * (0.5 - 0.5 * math.cos(math.pi * min(tm / t_ramp, 1.0)))
        s.advance(dt, n_block, external_forces={"tube": s.pressure_nodal_forces("tube", inner, p)})
        if s.time > t_ramp:
            ur = np.hypot(b.x[:, 0], b.x[:, 1]) - R0
            ur_a.append(ur[ia].mean())
            ur_b.append(ur[ib].mean())
    E, nu = MAT.youngs_modulus, MAT.poisson_ratio
    Al = P0 * A_IN ** 2 / (B_OUT ** 2 - A_IN ** 2)
    Bl = P0 * A_IN ** 2 * B_OUT ** 2 / (B_OUT ** 2 - A_IN ** 2)
    u = lambda r: (1 + nu) / E * ((1 - 2 * nu) * Al * r + Bl / r)  # noqa: E731
    ua, ub = np.mean(ur_a), np.mean(ur_b)
    # hoop and radial stress of the mid-wall cells (rotated to the cell's polar frame)
    xc = b.X0[b.cells].mean(axis=1)
    rc, th = np.hypot(xc[:, 0], xc[:, 1]), np.arctan2(xc[:, 1], xc[:, 0])
    mid = np.abs(rc - 0.15) < 0.006
    sxx, syy, sxy = (b.cell_stress[mid, k] for k in (0, 1, 3))
    c, sn = np.cos(th[mid]), np.sin(th[mid])
    hoop = sxx * sn ** 2 + syy * c ** 2 - 2 * sxy * sn * c
    rad = sxx * c ** 2 + syy * sn ** 2 + 2 * sxy * sn * c
    hoop_ref = (Al + Bl / rc[mid] ** 2).mean()
    rad_ref = (Al - Bl / rc[mid] ** 2).mean()
    print(f"\nLamé 3D sector ({len(b.cells)} tets, {s.step_count} steps): u(a) {ua * 1e6:.3f} um vs "
          f"{u(A_IN) * 1e6:.3f} ({ua / u(A_IN) - 1:+.3%}), u(b) {ub * 1e6:.3f} um vs "
          f"{u(B_OUT) * 1e6:.3f} ({ub / u(B_OUT) - 1:+.3%}), mid-wall hoop {hoop.mean() / 1e6:.2f} "
          f"MPa vs {hoop_ref / 1e6:.2f} ({hoop.mean() / hoop_ref - 1:+.3%}), radial "
          f"{rad.mean() / 1e6:.2f} vs {rad_ref / 1e6:.2f} ({rad.mean() / rad_ref - 1:+.3%}), "
          f"oscillation u(a) +- {np.std(ur_a) / ua:.2%}")
    # energy ledger: the work of the follower pressure = kinetic + elastic + bulk-viscous
    e = s.energies()
    print(f"ledger: external work {e['external_work_J']:.4g} J, elastic {e['elastic_J']:.4g} J, "
          f"balance error {e['balance_error_J'] / e['external_work_J']:.2e} of the work")
    assert abs(e["balance_error_J"]) < 0.01 * e["external_work_J"]
    assert ua == pytest.approx(u(A_IN), rel=0.01)
    assert ub == pytest.approx(u(B_OUT), rel=0.01)
    assert hoop.mean() == pytest.approx(hoop_ref, rel=0.01)
    assert rad.mean() == pytest.approx(rad_ref, rel=0.03)


def test_kinetic_damping_relaxes_the_3d_sector_to_lame():
    """The 2D kinetic-damping check (tests/mechanics/test_kinetic_damping.py) on the 3D sector: a
    step pressure, held, relaxes to Lamé's static u(a) within 1 %, with the kinetic energy gone
    and the removed energy closing the ledger; static: external work = 2 x elastic (Clapeyron)."""
    tol = 1e-9
    fixed = ((lambda x: np.abs(x[0]) < tol, (0,)), (lambda x: np.abs(x[1]) < tol, (1,)),
             (lambda x: np.isclose(x[2], 0.0) | np.isclose(x[2], H), (2,)))
    s = ExplicitSolver3D([BodySpec("tube", quarter_tube(), MAT, initial_velocity=(0, 0, 0),
                                   fixed=fixed)], comm=MPI.COMM_SELF)
    s.kinetic_damping = True
    b = s.bodies["tube"]
    inner = lambda x: x[0] ** 2 + x[1] ** 2 < (A_IN + 1e-3) ** 2  # noqa: E731
    R0 = np.hypot(b.X0[:, 0], b.X0[:, 1])
    ia = np.flatnonzero(np.isclose(R0, A_IN))
    dt = 0.9 * s.stable_time_step()
    ua = []
    for _ in range(300):
        s.advance(dt, 10, external_forces={"tube": s.pressure_nodal_forces("tube", inner, P0)})
        ua.append((np.hypot(b.x[ia, 0], b.x[ia, 1]) - R0[ia]).mean())
    E, nu = MAT.youngs_modulus, MAT.poisson_ratio
    Al = P0 * A_IN ** 2 / (B_OUT ** 2 - A_IN ** 2)
    Bl = P0 * A_IN ** 2 * B_OUT ** 2 / (B_OUT ** 2 - A_IN ** 2)
    ref = (1 + nu) / E * ((1 - 2 * nu) * Al * A_IN + Bl / A_IN)
    e = s.energies()
    ua = np.array(ua)
    print(f"\nkinetic damping, 3D sector: u(a) {ua[-1] * 1e6:.3f} um vs static {ref * 1e6:.3f} "
          f"({ua[-1] / ref - 1:+.3%}), kinetic/elastic {e['kinetic_J'] / e['elastic_J']:.1e}, "
          f"removed {e['kinetic_damping_J']:.4g} J of {e['external_work_J']:.4g} J")
    assert ua[-1] == pytest.approx(ref, rel=0.01)
    assert np.abs(ua[-20:] / ref - 1).max() < 0.01
    assert e["kinetic_J"] < 1e-4 * e["elastic_J"]
    assert abs(e["balance_error_J"]) < 1e-3 * e["external_work_J"]
    assert e["elastic_J"] == pytest.approx(0.5 * e["external_work_J"], rel=0.02)
