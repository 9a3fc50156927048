"""Uniaxial-strain elastic-plastic wave (plane strain strip, lateral velocity fixed) hitting a rigid
wall at V = 60 m/s.

Analytic reference (small strain, J2, linear hardening A, e.g. Meyers, Dynamic Behavior of
Materials, ch. 7): elastic precursor speed c_e = sqrt((K + 4G/3) / rho), Hugoniot elastic limit
sigma_HEL = sigma_0 (K + 4G/3) / (2G), plastic wave speed c_p = sqrt((K + 4/3 G A / (A + 3G)) / rho),
and behind the plastic front sigma = sigma_HEL + rho c_p (V - sigma_HEL / (rho c_e)).
"""
import math

import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import BodySpec, ExplicitSolver, RigidWallSpec
from pulseform.solvers.dolfinx.verification import PAPER_BAR_MATERIAL as MAT

V0 = 60.0
L = 1.0


def _crossing(t, s, level):
    """First time the (compressive, negative) stress goes below ``level``, interpolated."""
    i = int(np.argmax(s < level))
    assert s[i] < level and i > 0
    return t[i - 1] + (t[i] - t[i - 1]) * (s[i - 1] - level) / (s[i - 1] - s[i])


def test_uniaxial_strain_plastic_wave():
    G, K, rho = MAT.shear_modulus, MAT.bulk_modulus, MAT.density
    A, s0 = MAT.hardening_modulus, MAT.yield_stress
    ce = math.sqrt((K + 4 * G / 3) / rho)
    cp = math.sqrt((K + 4.0 / 3.0 * G * A / (A + 3 * G)) / rho)
    hel = s0 * (K + 4 * G / 3) / (2 * G)
    u_hel = hel / (rho * ce)
    s_fin = hel + rho * cp * (V0 - u_hel)
    nx = 1000
    msh = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([0.0, 0.0]), np.array([L, L / nx])],
                                 [nx, 1])
    allnodes = lambda x: np.full(x.shape[1], True)  # noqa: E731
    body = BodySpec("strip", msh, MAT, initial_velocity=(-V0, 0.0), fixed=((allnodes, (1,)),))
    s = ExplicitSolver([body], formulation="plane_strain",
                       rigid_walls=(RigidWallSpec((0.0, 0.0), (1.0, 0.0)),), comm=msh.comm)
    b = s.bodies["strip"]
    xc = b.X0[b.cells].mean(axis=1)[:, 0]
    stations = (0.3, 0.6)
    sel = [np.flatnonzero(np.abs(xc - xs) < 0.5 * L / nx + 1e-12) for xs in stations]
    t_end = 0.22e-3          # before the free-end reflection comes back to x = 0.6
    ts, hist = [], []
    dt = s.stable_time_step()
    while s.time < t_end:
        s.advance(dt)
        ts.append(s.time)
        hist.append([b.cell_stress[c, 0].mean() for c in sel])
        dt = s.stable_time_step()
    t = np.array(ts)
    h = np.array(hist)
    te = [_crossing(t, h[:, k], -0.5 * hel) for k in range(2)]
    tp = [_crossing(t, h[:, k], -0.5 * (hel + s_fin)) for k in range(2)]
    ce_num = (stations[1] - stations[0]) / (te[1] - te[0])
    cp_num = (stations[1] - stations[0]) / (tp[1] - tp[0])
    # elastic plateau between the fronts at the far station, final plateau after the plastic one
    mid = 0.5 * (te[1] + tp[1])
    half = 0.25 * (tp[1] - te[1])
    hel_num = -h[(t > mid - half) & (t < mid + half), 1].mean()
    fin_num = -h[(t > tp[1] + 10e-6) & (t < t_end), 1].mean()
    print(f"\nelastic front {ce_num:.1f} m/s (analytic {ce:.1f}, err {ce_num / ce - 1:+.2%}); "
          f"plastic front {cp_num:.1f} m/s ({cp:.1f}, {cp_num / cp - 1:+.2%}); "
          f"HEL {hel_num / 1e6:.1f} MPa ({hel / 1e6:.1f}, {hel_num / hel - 1:+.2%}); "
          f"final {fin_num / 1e6:.1f} MPa ({s_fin / 1e6:.1f}, {fin_num / s_fin - 1:+.2%})")
    assert ce_num == pytest.approx(ce, rel=0.03)
    assert cp_num == pytest.approx(cp, rel=0.03)
    assert hel_num == pytest.approx(hel, rel=0.03)
    assert fin_num == pytest.approx(s_fin, rel=0.03)
    assert b.eps_p.max() > 0.005
