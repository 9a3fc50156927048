"""Compiled (numba) element kernel of the 2D explicit step on six-node triangles (:mod:`.tri6`): the linear
triangle's point update (:func:`.element_math.point_update`: the Hughes-Winget rotation of the old stress,
hypo-elastic predictor, J2 radial return with any flow curve and rate law, the plane-stress secant iteration) at
each of the three Gauss points with the velocity gradient on the mid-step configuration (axisymmetry: the hoop
rate v_r / r at the Gauss point), adiabatic heating, bulk viscosity, and the internal forces by the Gauss rule on
the end configuration, f_a = sum_q w_q det J_q W_q (sigma_q - q_q I) grad N_a, W_q the thickness or 2 pi r_q
(axisymmetry: plus the hoop term 2 pi w_q det J_q (sigma_zz - q) N_a(q) on the radial component).

Critical step: the element's largest frequency under the HRZ mass bounds the mesh's; its ratio to the linear
kernel's estimate (the corner triangle's altitude on its longest edge over the wave speed) is taken on the
reference mesh by :func:`.tri6.critical_step_factor` and applied to that estimate on the deformed mesh at every
step, with the bulk viscosity's reduction sqrt(1 + xi^2) - xi (as :mod:`.tet10_kernel` does in 3D).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from .element_math import (FM, MODE_AXISYMMETRIC, MODE_PLANE_STRAIN, MODE_PLANE_STRESS, P_B1, P_B2, P_BULK, P_G,
                           P_K, P_MODE, P_RHO, P_THICK, heated, point_update)
from .kernel_layout import P_T0
from .tri6 import QP_DERIVATIVES, QP_VALUES, QP_WEIGHTS

__all__ = ["tri6_step", "tri6_critical_dt", "Tri6Kernel"]


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def _gradients(xe, dN, q, g):
    """Shape-function gradients ``g`` (6, 2) at Gauss point ``q`` of the cell at ``xe`` (6, 2); returns det J
    (not positive: inverted, ``g`` unset)."""
    j00 = j01 = j10 = j11 = 0.0
    for a in range(6):
        j00 += xe[a, 0] * dN[q, a, 0]
        j01 += xe[a, 0] * dN[q, a, 1]
        j10 += xe[a, 1] * dN[q, a, 0]
        j11 += xe[a, 1] * dN[q, a, 1]
    det = j00 * j11 - j01 * j10
    if not det > 0.0:
        return det
    inv = 1.0 / det
    i00, i01, i10, i11 = j11 * inv, -j01 * inv, -j10 * inv, j00 * inv
    for a in range(6):
        g[a, 0] = dN[q, a, 0] * i00 + dN[q, a, 1] * i10
        g[a, 1] = dN[q, a, 0] * i01 + dN[q, a, 1] * i11
    return det


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def _corner_length(xe):
    """The corner triangle's altitude on its longest edge, 2 A / l_max, m (the linear kernel's length)."""
    x0, y0, x1, y1, x2, y2 = xe[0, 0], xe[0, 1], xe[1, 0], xe[1, 1], xe[2, 0], xe[2, 1]
    tn = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    l01 = (x1 - x0) * (x1 - x0) + (y1 - y0) * (y1 - y0)
    l12 = (x2 - x1) * (x2 - x1) + (y2 - y1) * (y2 - y1)
    l20 = (x0 - x2) * (x0 - x2) + (y0 - y2) * (y0 - y2)
    return tn / math.sqrt(max(l01, max(l12, l20)))


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def _radius(xe, Nq, q):
    """The radius r = sum_a N_a(q) x_a (m) of Gauss point ``q`` of the cell at ``xe``."""
    r = 0.0
    for a in range(6):
        r += Nq[q, a] * xe[a, 0]
    return r


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def tri6_step(cells, x, v, dt, prm, stress, eps_p, f_int, acc, temp, dN, Nq, wq, factor):
    """Explicit update of the six-node triangles ``cells`` (nc, 6): the arguments of
    :func:`.kernels.element_step` (positions x^{n+1} (N, 2) m, half-step velocities (N, 2) m/s, the step dt s,
    the parameters of :func:`.kernels.pack_parameters`) with ``stress`` (nc * 3, 4) Pa, ``eps_p`` and ``temp``
    (nc * 3,) per Gauss point (``temp`` empty: no temperature), ``f_int`` (N, 2) N to which the forces are added,
    ``acc`` as there, plus the Gauss rule (``dN`` (3, 6, 2) shape-function derivatives, ``Nq`` (3, 6) values,
    ``wq`` (3,) weights) and the critical-step ``factor`` of :func:`.tri6.critical_step_factor`. Returns the
    smallest element critical step (CFL 1), s."""
    rho = prm[P_RHO]
    G = prm[P_G]
    lam = prm[P_K] - 2.0 * G / 3.0
    c = math.sqrt((prm[P_K] + 4.0 * G / 3.0) / rho)
    b1, b2 = prm[P_B1], prm[P_B2]
    bulk = prm[P_BULK] > 0.0
    thick = prm[P_THICK]
    mode = int(prm[P_MODE])
    axi = mode == MODE_AXISYMMETRIC
    twopi = 2.0 * math.pi
    hdt = 0.5 * dt
    xe = np.empty((6, 2))
    xm = np.empty((6, 2))
    ve = np.empty((6, 2))
    gm = np.empty((3, 6, 2))
    g1 = np.empty((3, 6, 2))
    detm = np.empty(3)
    det1 = np.empty(3)
    dtmin = 1e300
    wp = 0.0
    wv = 0.0
    acc[2] = -1.0
    for e in range(cells.shape[0]):
        for a in range(6):
            n = cells[e, a]
            for i in range(2):
                xe[a, i] = x[n, i]
                ve[a, i] = v[n, i]
                xm[a, i] = x[n, i] - hdt * v[n, i]
        ok = True
        for q in range(3):
            detm[q] = _gradients(xm, dN, q, gm[q])
            det1[q] = _gradients(xe, dN, q, g1[q])
            if not (detm[q] > 0.0 and det1[q] > 0.0):
                ok = False
        if not ok:
            if acc[2] < 0.0:
                acc[2] = e
            continue
        le = _corner_length(xe)
        xi_max = 0.0
        for q in range(3):
            lxx = lxy = lyx = lyy = 0.0
            for a in range(6):
                lxx += ve[a, 0] * gm[q, a, 0]
                lxy += ve[a, 0] * gm[q, a, 1]
                lyx += ve[a, 1] * gm[q, a, 0]
                lyy += ve[a, 1] * gm[q, a, 1]
            dxy = 0.5 * (lxy + lyx)
            w = 0.5 * (lxy - lyx)
            rm = _radius(xm, Nq, q) if axi else 1.0
            if axi:
                vr = 0.0
                for a in range(6):
                    vr += Nq[q, a] * ve[a, 0]
                dzz = vr / rm
            elif mode == MODE_PLANE_STRAIN:
                dzz = 0.0
            else:
                dzz = -lam / (lam + 2.0 * G) * (lxx + lyy)
            r = 3 * e + q
            T = temp[r] if temp.shape[0] > 0 else prm[P_T0]
            ep = eps_p[r]
            nxx, nyy, nzz, nxy, dep, sy, hr, dzz = point_update(stress[r, 0], stress[r, 1], stress[r, 2],
                                                                stress[r, 3], ep, T, lxx, lyy, dzz, dxy, w, dt, prm)
            stress[r, 0], stress[r, 1], stress[r, 2], stress[r, 3] = nxx, nyy, nzz, nxy
            eps_p[r] = ep + dep
            if temp.shape[0] > 0:
                temp[r] = heated(T, sy, dep, prm)
            trd = lxx + lyy + dzz
            qb = 0.0
            xi = 0.0
            if bulk:
                qb = b1 * rho * c * le * (-trd)
                xi = b1
                if trd < 0.0:
                    qb += rho * (b2 * le * trd) ** 2
                    xi += b2 * b2 * le / c * (-trd)
            xi_max = max(xi_max, xi)
            volm = wq[q] * detm[q] * (twopi * rm if axi else thick)
            wp += (sy + hr * dep) * dep * volm
            wv += -qb * ((lxx + lyy) if mode == MODE_PLANE_STRESS else trd) * volm * dt
            wd = wq[q] * det1[q]
            vol = wd * (twopi * _radius(xe, Nq, q) if axi else thick)
            sxx = nxx - qb
            syy = nyy - qb
            hoop = twopi * wd * (nzz - qb) if axi else 0.0
            for a in range(6):
                n = cells[e, a]
                gx, gy = g1[q, a, 0], g1[q, a, 1]
                f_int[n, 0] += vol * (sxx * gx + nxy * gy) + hoop * Nq[q, a]
                f_int[n, 1] += vol * (nxy * gx + syy * gy)
        dte = factor * le / c * (math.sqrt(1.0 + xi_max * xi_max) - xi_max)
        if dte < dtmin:
            dtmin = dte
    acc[0] += wp
    acc[1] += wv
    return dtmin


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def tri6_critical_dt(cells, x, prm, factor):
    """Smallest element critical step (CFL 1, at rest: the linear bulk-viscosity reduction only) of six-node
    cells, s: ``factor`` times the corner triangle's altitude over the wave speed; -1.0 if a corner triangle is
    inverted."""
    c = math.sqrt((prm[P_K] + 4.0 * prm[P_G] / 3.0) / prm[P_RHO])
    xi = prm[P_B1] if prm[P_BULK] > 0.0 else 0.0
    red = math.sqrt(1.0 + xi * xi) - xi
    xe = np.empty((3, 2))
    dtmin = 1e300
    for e in range(cells.shape[0]):
        for a in range(3):
            for i in range(2):
                xe[a, i] = x[cells[e, a], i]
        le = _corner_length(xe)
        if not le > 0.0:
            return -1.0
        dtmin = min(dtmin, factor * le / c * red)
    return dtmin


class Tri6Kernel:
    """The element kernel of a six-node body (serial): :func:`.kernels.element_step`'s signature, with the body's
    critical-step factor (:func:`.tri6.critical_step_factor`)."""

    def __init__(self, factor: float):
        self.factor = float(factor)

    def __call__(self, cells, x, v, dt, prm, stress, eps_p, f_int, acc, work=None, temp=None) -> float:
        temp = np.empty(0) if temp is None or not temp.shape[0] else temp
        return tri6_step(cells, x, v, dt, prm, stress, eps_p, f_int, acc, temp, QP_DERIVATIVES, QP_VALUES,
                         QP_WEIGHTS, self.factor)

    def critical_dt(self, cells, x, prm) -> float:
        """The cells' smallest critical step at rest (CFL 1), s; -1 if one is inverted."""
        return tri6_critical_dt(cells, x, prm, self.factor)
