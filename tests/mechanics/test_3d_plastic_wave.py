"""Uniaxial-strain elastic-plastic wave in 3D (issue 20): a column of tetrahedra (1 m long, one
brick of six tetrahedra per 1 mm cross section, every node held laterally: v_y = v_z = 0) hits a
rigid wall at V = 60 m/s — the 3D counterpart of tests/mechanics/test_plastic_wave.py.

Analytic reference (small strain, J2, linear hardening A, e.g. Meyers, Dynamic Behavior of
Materials, ch. 7): elastic precursor speed c_e = sqrt((K + 4G/3) / rho), Hugoniot elastic limit
sigma_HEL = sigma_0 (K + 4G/3) / (2G), plastic wave speed c_p = sqrt((K + 4/3 G A / (A + 3G)) / rho),
and behind the plastic front sigma = sigma_HEL + rho c_p (V - sigma_HEL / (rho c_e)); 3 % as in 2D.
The cells that flow in a step end it on the current yield surface (radial return): von Mises
stress = sigma_0 + A eps_p, to round-off.
"""
import math

import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import BodySpec, ExplicitSolver3D, RigidWallSpec
from pulseform.solvers.dolfinx.verification import PAPER_BAR_MATERIAL as MAT

V0 = 60.0
L = 1.0


def _crossing(t, s, level):
    """First time the (compressive, negative) stress goes below ``level``, interpolated."""
    i = int(np.argmax(s < level))
    assert s[i] < level and i > 0
    return t[i - 1] + (t[i] - t[i - 1]) * (s[i - 1] - level) / (s[i - 1] - s[i])


def test_uniaxial_strain_plastic_wave_3d():
    G, K, rho = MAT.shear_modulus, MAT.bulk_modulus, MAT.density
    A, s0 = MAT.hardening_modulus, MAT.yield_stress
    ce = math.sqrt((K + 4 * G / 3) / rho)
    cp = math.sqrt((K + 4.0 / 3.0 * G * A / (A + 3 * G)) / rho)
    hel = s0 * (K + 4 * G / 3) / (2 * G)
    u_hel = hel / (rho * ce)
    s_fin = hel + rho * cp * (V0 - u_hel)
    nx = 1000
    h = L / nx
    msh = dmesh.create_box(MPI.COMM_SELF, [np.zeros(3), np.array([L, h, h])], [nx, 1, 1],
                           dmesh.CellType.tetrahedron)
    allnodes = lambda x: np.full(x.shape[1], True)  # noqa: E731
    body = BodySpec("column", msh, MAT, initial_velocity=(-V0, 0.0, 0.0),
                    fixed=((allnodes, (1, 2)),))
    s = ExplicitSolver3D([body], rigid_walls=(RigidWallSpec((0.0, 0.0, 0.0), (1.0, 0.0, 0.0)),),
                         comm=msh.comm)
    b = s.bodies["column"]
    xc = b.X0[b.cells].mean(axis=1)[:, 0]
    stations = (0.3, 0.6)
    sel = [np.flatnonzero(np.abs(xc - xs) < 0.5 * h + 1e-12) for xs in stations]
    t_end = 0.22e-3          # before the free-end reflection comes back to x = 0.6
    ts, hist = [], []
    dt = s.stable_time_step()
    flowing = 0
    while s.time < t_end:
        ep_prev = b.eps_p.copy()
        s.advance(dt)
        if not flowing and s.time > 0.1e-3:        # the plastic front is inside the column
            pl = b.eps_p > ep_prev
            flowing = int(pl.sum())
            sy = s0 + A * b.eps_p[pl]
            on_surface = np.abs(b.von_mises[pl] - sy).max() / sy.max()
        ts.append(s.time)
        hist.append([b.cell_stress[c, 0].mean() for c in sel])
        dt = s.stable_time_step()
    t = np.array(ts)
    hh = np.array(hist)
    te = [_crossing(t, hh[:, k], -0.5 * hel) for k in range(2)]
    tp = [_crossing(t, hh[:, k], -0.5 * (hel + s_fin)) for k in range(2)]
    ce_num = (stations[1] - stations[0]) / (te[1] - te[0])
    cp_num = (stations[1] - stations[0]) / (tp[1] - tp[0])
    mid = 0.5 * (te[1] + tp[1])
    half = 0.25 * (tp[1] - te[1])
    hel_num = -hh[(t > mid - half) & (t < mid + half), 1].mean()
    fin_num = -hh[(t > tp[1] + 10e-6) & (t < t_end), 1].mean()
    print(f"\n3D column ({len(b.cells)} tets, {s.step_count} steps): elastic front {ce_num:.1f} m/s "
          f"(analytic {ce:.1f}, err {ce_num / ce - 1:+.2%}); plastic front {cp_num:.1f} m/s "
          f"({cp:.1f}, {cp_num / cp - 1:+.2%}); HEL {hel_num / 1e6:.1f} MPa ({hel / 1e6:.1f}, "
          f"{hel_num / hel - 1:+.2%}); final {fin_num / 1e6:.1f} MPa ({s_fin / 1e6:.1f}, "
          f"{fin_num / s_fin - 1:+.2%}); eps_p max {b.eps_p.max():.4f}; {flowing} cells flowing at "
          f"0.1 ms, on the yield surface to {on_surface:.1e}")
    assert ce_num == pytest.approx(ce, rel=0.03)
    assert cp_num == pytest.approx(cp, rel=0.03)
    assert hel_num == pytest.approx(hel, rel=0.03)
    assert fin_num == pytest.approx(s_fin, rel=0.03)
    assert b.eps_p.max() > 0.005
    assert flowing > 0 and on_surface <= 1e-12
