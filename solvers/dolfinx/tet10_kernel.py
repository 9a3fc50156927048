"""Compiled (numba) element kernel of the 3D explicit step on ten-node tetrahedra (:mod:`.tet10`): the linear
kernel's update (:func:`.tet_kernel.tet_cell`: the velocity gradient on the mid-step configuration, the
Hughes-Winget rotation of the old stress, hypo-elastic predictor, J2 radial return with the linear law, the
rate laws and the flow curves, adiabatic heating, bulk viscosity) at each of the four Gauss points, and the
internal forces by the Gauss rule on the end configuration, f_a = sum_q w_q det J_q (sigma_q - q_q I) grad N_a.

Critical step: the element's largest frequency under the HRZ mass bounds the mesh's (the element eigenvalue
inequality); its ratio to the linear kernel's estimate (the corner tetrahedron's smallest altitude over the
wave speed) is taken on the reference mesh by :func:`.tet10.critical_step_factor` and applied to that estimate
on the deformed mesh at every step, with the bulk viscosity's reduction sqrt(1 + xi^2) - xi.

Selective mass scaling (:mod:`.mass_scaling`): ``rho_scale`` (nc,) multiplies each cell's density in its wave speed
c_e = sqrt((K + 4 G / 3) / (rho s_e)), hence its critical step (times sqrt(s_e)), and in its bulk viscosity (rho_e c_e
and rho_e); an empty ``rho_scale`` is the unscaled kernel, operation for operation.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from .element_math import (FM, P_B1, P_B2, P_BULK, P_G, P_H, P_K, P_R1, P_R2, P_RATE, P_RHO, P_SY0,
                           general_material, heated, rate_factor_at)
from .flow_curves import plastic_return
from .kernel_layout import P_T0

__all__ = ["tet10_step", "tet10_critical_dt", "tet10_cell_steps"]


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def _inverse(J, out):
    """Inverse of the 3x3 ``J`` into ``out``; returns det J."""
    c00 = J[1, 1] * J[2, 2] - J[1, 2] * J[2, 1]
    c01 = J[1, 2] * J[2, 0] - J[1, 0] * J[2, 2]
    c02 = J[1, 0] * J[2, 1] - J[1, 1] * J[2, 0]
    det = J[0, 0] * c00 + J[0, 1] * c01 + J[0, 2] * c02
    if not det > 0.0:
        return det
    inv = 1.0 / det
    out[0, 0] = c00 * inv
    out[1, 0] = c01 * inv
    out[2, 0] = c02 * inv
    out[0, 1] = (J[0, 2] * J[2, 1] - J[0, 1] * J[2, 2]) * inv
    out[1, 1] = (J[0, 0] * J[2, 2] - J[0, 2] * J[2, 0]) * inv
    out[2, 1] = (J[0, 1] * J[2, 0] - J[0, 0] * J[2, 1]) * inv
    out[0, 2] = (J[0, 1] * J[1, 2] - J[0, 2] * J[1, 1]) * inv
    out[1, 2] = (J[0, 2] * J[1, 0] - J[0, 0] * J[1, 2]) * inv
    out[2, 2] = (J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0]) * inv
    return det


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def _nodal_gradient(fe, dN, q, out):
    """``out[i, j]`` = Σ_a fe[a, i] dN[q, a, j]: the gradient at Gauss point ``q`` of the nodal field ``fe`` (10, 3)
    for the shape-function derivatives ``dN`` (reference ones: the Jacobian; physical ones: a velocity gradient)."""
    for i in range(3):
        for j in range(3):
            s = 0.0
            for a in range(10):
                s += fe[a, i] * dN[q, a, j]
            out[i, j] = s


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def _gradients(xe, dN, q, J, Ji, g):
    """Shape-function gradients ``g`` (10, 3) at Gauss point ``q`` of the cell at ``xe`` (10, 3); returns
    det J (not positive: inverted, ``g`` unset)."""
    _nodal_gradient(xe, dN, q, J)
    det = _inverse(J, Ji)
    if not det > 0.0:
        return det
    for a in range(10):
        for i in range(3):
            g[a, i] = dN[q, a, 0] * Ji[0, i] + dN[q, a, 1] * Ji[1, i] + dN[q, a, 2] * Ji[2, i]
    return det


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def _corner_length(xe):
    """The corner tetrahedron's smallest altitude, 3 V / largest face area, m."""
    ax, ay, az = xe[1, 0] - xe[0, 0], xe[1, 1] - xe[0, 1], xe[1, 2] - xe[0, 2]
    bx, by, bz = xe[2, 0] - xe[0, 0], xe[2, 1] - xe[0, 1], xe[2, 2] - xe[0, 2]
    cx, cy, cz = xe[3, 0] - xe[0, 0], xe[3, 1] - xe[0, 1], xe[3, 2] - xe[0, 2]
    n1x, n1y, n1z = by * cz - bz * cy, bz * cx - bx * cz, bx * cy - by * cx
    n2x, n2y, n2z = cy * az - cz * ay, cz * ax - cx * az, cx * ay - cy * ax
    n3x, n3y, n3z = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    det = ax * n1x + ay * n1y + az * n1z
    n0x, n0y, n0z = n1x + n2x + n3x, n1y + n2y + n3y, n1z + n2z + n3z
    amax = max(max(n0x * n0x + n0y * n0y + n0z * n0z, n1x * n1x + n1y * n1y + n1z * n1z),
               max(n2x * n2x + n2y * n2y + n2z * n2z, n3x * n3x + n3y * n3y + n3z * n3z))
    return det / math.sqrt(amax)


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def _point(stress, eps_p, temp, r, Lg, dt, prm):
    """The stress update of the Gauss point (row) ``r`` with the velocity gradient ``Lg`` (3, 3), 1/s, over
    ``dt``: stress, plastic strain and temperature updated in place; returns (deps_p, yield stress (Pa) and
    hardening (Pa) of the linear law's dissipation, trace of the rate of deformation (1/s))."""
    G = prm[P_G]
    lam = prm[P_K] - 2.0 * G / 3.0
    hdt = 0.5 * dt
    dxx, dyy, dzz = Lg[0, 0], Lg[1, 1], Lg[2, 2]
    dxy = 0.5 * (Lg[0, 1] + Lg[1, 0])
    dyz = 0.5 * (Lg[1, 2] + Lg[2, 1])
    dxz = 0.5 * (Lg[0, 2] + Lg[2, 0])
    a01 = hdt * 0.5 * (Lg[0, 1] - Lg[1, 0])
    a02 = hdt * 0.5 * (Lg[0, 2] - Lg[2, 0])
    a12 = hdt * 0.5 * (Lg[1, 2] - Lg[2, 1])
    k = 2.0 / (1.0 + a01 * a01 + a02 * a02 + a12 * a12)
    q00 = 1.0 - k * (a01 * a01 + a02 * a02)
    q11 = 1.0 - k * (a01 * a01 + a12 * a12)
    q22 = 1.0 - k * (a02 * a02 + a12 * a12)
    q01 = k * (a01 - a02 * a12)
    q10 = k * (-a01 - a02 * a12)
    q02 = k * (a02 + a01 * a12)
    q20 = k * (-a02 + a01 * a12)
    q12 = k * (a12 - a01 * a02)
    q21 = k * (-a12 - a01 * a02)
    sxx, syy, szz = stress[r, 0], stress[r, 1], stress[r, 2]
    sxy, syz, sxz = stress[r, 3], stress[r, 4], stress[r, 5]
    t00 = q00 * sxx + q01 * sxy + q02 * sxz
    t01 = q00 * sxy + q01 * syy + q02 * syz
    t02 = q00 * sxz + q01 * syz + q02 * szz
    t10 = q10 * sxx + q11 * sxy + q12 * sxz
    t11 = q10 * sxy + q11 * syy + q12 * syz
    t12 = q10 * sxz + q11 * syz + q12 * szz
    t20 = q20 * sxx + q21 * sxy + q22 * sxz
    t21 = q20 * sxy + q21 * syy + q22 * syz
    t22 = q20 * sxz + q21 * syz + q22 * szz
    rxx = t00 * q00 + t01 * q01 + t02 * q02
    ryy = t10 * q10 + t11 * q11 + t12 * q12
    rzz = t20 * q20 + t21 * q21 + t22 * q22
    rxy = t00 * q10 + t01 * q11 + t02 * q12
    ryz = t10 * q20 + t11 * q21 + t12 * q22
    rxz = t00 * q20 + t01 * q21 + t02 * q22
    trd = dxx + dyy + dzz
    mr = trd / 3.0
    ep = eps_p[r]
    rate = math.sqrt(2.0 / 3.0 * ((dxx - mr) ** 2 + (dyy - mr) ** 2 + (dzz - mr) ** 2
                                  + 2.0 * (dxy * dxy + dyz * dyz + dxz * dxz)))
    rid = int(prm[P_RATE])
    fac = rate_factor_at(rid, prm[P_R1], prm[P_R2], rate) if rid != 0 else 1.0
    general = general_material(prm)
    sy = 0.0
    hr = 0.0
    tc = 0.0
    if general:
        tc = temp[r] if temp.shape[0] > 0 else prm[P_T0]
    else:
        sy = (prm[P_SY0] + prm[P_H] * ep) * fac
        hr = prm[P_H] * fac
    ltr = lam * trd * dt
    g2 = 2.0 * G * dt
    txx = rxx + ltr + g2 * dxx
    tyy = ryy + ltr + g2 * dyy
    tzz = rzz + ltr + g2 * dzz
    txy = rxy + g2 * dxy
    tyz = ryz + g2 * dyz
    txz = rxz + g2 * dxz
    p = (txx + tyy + tzz) / 3.0
    exx, eyy, ezz = txx - p, tyy - p, tzz - p
    qm = math.sqrt(1.5 * (exx * exx + eyy * eyy + ezz * ezz + 2.0 * (txy * txy + tyz * tyz + txz * txz)))
    dep = 0.0
    if general:
        dep, sy = plastic_return(qm, G, ep, rate, tc, fac, prm)
        plastic = dep > 0.0
        if temp.shape[0] > 0:
            temp[r] = heated(tc, sy, dep, prm)
    else:
        plastic = qm > sy
        if plastic:
            dep = (qm - sy) / (3.0 * G + hr)
    if plastic:
        f = 1.0 - 3.0 * G * dep / qm
        txx, tyy, tzz = exx * f + p, eyy * f + p, ezz * f + p
        txy *= f
        tyz *= f
        txz *= f
    stress[r, 0], stress[r, 1], stress[r, 2] = txx, tyy, tzz
    stress[r, 3], stress[r, 4], stress[r, 5] = txy, tyz, txz
    eps_p[r] = ep + dep
    return dep, sy, hr, trd


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def tet10_step(cells, x, v, dt, prm, stress, eps_p, f_int, acc, temp, dN, wq, factor, rho_scale):
    """Explicit update of the ten-node tetrahedra ``cells`` (nc, 10): the arguments of
    :func:`.tet_kernel.tet_step` with ``stress`` (nc * 4, 6), ``eps_p`` and ``temp`` (nc * 4,) per Gauss point,
    plus the Gauss rule (``dN`` (4, 10, 3) shape-function derivatives, ``wq`` (4,) weights), the critical-step
    ``factor`` of :func:`.tet10.critical_step_factor` and the cells' density factors ``rho_scale`` (nc,), >= 1
    (selective mass scaling; empty: none). Returns the smallest element critical step (CFL 1), s."""
    rho = prm[P_RHO]
    c = math.sqrt((prm[P_K] + 4.0 * prm[P_G] / 3.0) / rho)
    scaled = rho_scale.shape[0] > 0
    b1, b2 = prm[P_B1], prm[P_B2]
    bulk = prm[P_BULK] > 0.0
    hdt = 0.5 * dt
    xe = np.empty((10, 3))
    xm = np.empty((10, 3))
    ve = np.empty((10, 3))
    J = np.empty((3, 3))
    Ji = np.empty((3, 3))
    gm = np.empty((4, 10, 3))
    g1 = np.empty((4, 10, 3))
    detm = np.empty(4)
    det1 = np.empty(4)
    Lg = np.empty((3, 3))
    dtmin = 1e300
    wp = 0.0
    wv = 0.0
    acc[2] = -1.0
    for e in range(cells.shape[0]):
        for a in range(10):
            n = cells[e, a]
            for i in range(3):
                xe[a, i] = x[n, i]
                ve[a, i] = v[n, i]
                xm[a, i] = x[n, i] - hdt * v[n, i]
        ok = True
        for q in range(4):
            detm[q] = _gradients(xm, dN, q, J, Ji, gm[q])
            det1[q] = _gradients(xe, dN, q, J, Ji, g1[q])
            if not (detm[q] > 0.0 and det1[q] > 0.0):
                ok = False
        if not ok:
            if acc[2] < 0.0:
                acc[2] = e
            continue
        le = _corner_length(xe)
        rho_e, c_e = rho, c
        if scaled:
            rho_e = rho * rho_scale[e]
            c_e = math.sqrt((prm[P_K] + 4.0 * prm[P_G] / 3.0) / rho_e)
        xi_max = 0.0
        for q in range(4):
            _nodal_gradient(ve, gm, q, Lg)
            r = 4 * e + q
            dep, sy, hr, trd = _point(stress, eps_p, temp, r, Lg, dt, prm)
            qb = 0.0
            xi = 0.0
            if bulk:
                qb = b1 * rho_e * c_e * le * (-trd)
                xi = b1
                if trd < 0.0:
                    qb += rho_e * (b2 * le * trd) ** 2
                    xi += b2 * b2 * le / c_e * (-trd)
            xi_max = max(xi_max, xi)
            volm = wq[q] * detm[q]
            wp += (sy + hr * dep) * dep * volm
            wv += -qb * trd * volm * dt
            w = wq[q] * det1[q]
            sxx = stress[r, 0] - qb
            syy = stress[r, 1] - qb
            szz = stress[r, 2] - qb
            sxy, syz, sxz = stress[r, 3], stress[r, 4], stress[r, 5]
            for a in range(10):
                n = cells[e, a]
                gx, gy, gz = g1[q, a, 0], g1[q, a, 1], g1[q, a, 2]
                f_int[n, 0] += w * (sxx * gx + sxy * gy + sxz * gz)
                f_int[n, 1] += w * (sxy * gx + syy * gy + syz * gz)
                f_int[n, 2] += w * (sxz * gx + syz * gy + szz * gz)
        dte = factor * le / c_e * (math.sqrt(1.0 + xi_max * xi_max) - xi_max)
        if dte < dtmin:
            dtmin = dte
    acc[0] += wp
    acc[1] += wv
    return dtmin


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def tet10_cell_steps(cells, x, prm, factor, rho_scale, out):
    """Each cell's critical step (CFL 1, at rest: the linear bulk-viscosity reduction only) into ``out`` (nc,), s:
    ``factor`` times the corner tetrahedron's altitude over the wave speed of the cell's density (times
    ``rho_scale[e]``, empty: none); returns False (``out`` partly set) if a corner tetrahedron is inverted."""
    cm = prm[P_K] + 4.0 * prm[P_G] / 3.0
    c = math.sqrt(cm / prm[P_RHO])
    scaled = rho_scale.shape[0] > 0
    xi = prm[P_B1] if prm[P_BULK] > 0.0 else 0.0
    red = math.sqrt(1.0 + xi * xi) - xi
    xe = np.empty((10, 3))
    for e in range(cells.shape[0]):
        for a in range(4):
            for i in range(3):
                xe[a, i] = x[cells[e, a], i]
        le = _corner_length(xe)
        if not le > 0.0:
            return False
        c_e = math.sqrt(cm / (prm[P_RHO] * rho_scale[e])) if scaled else c
        out[e] = factor * le / c_e * red
    return True


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def tet10_critical_dt(cells, x, prm, factor, rho_scale):
    """Smallest element critical step (CFL 1, at rest: the linear bulk-viscosity reduction only) of ten-node
    cells, s: the least of :func:`tet10_cell_steps`; -1.0 if a corner tetrahedron is inverted."""
    out = np.empty(cells.shape[0])
    if not tet10_cell_steps(cells, x, prm, factor, rho_scale, out):
        return -1.0
    dtmin = 1e300
    for e in range(out.shape[0]):
        dtmin = min(dtmin, out[e])
    return dtmin
