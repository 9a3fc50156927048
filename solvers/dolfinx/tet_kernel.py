"""Compiled (numba) element kernel of the 3D explicit step on linear tetrahedra: objective stress
update, J2 radial return with linear hardening (and the rate laws of :mod:`.material`), bulk
viscosity, internal nodal forces and element critical time steps in one fused pass over the cells;
plus the per-cell fields of the 3D ledger and outputs.

Conventions (the 3D counterparts of :mod:`.kernels`)
----------------------------------------------------
* Cells are tetrahedra given by four local node (row) indices, oriented so that
  (x1 - x0) . ((x2 - x0) x (x3 - x0)) > 0 (six times the volume).
* Stress per cell in Voigt order ``[xx, yy, zz, xy, yz, xz]`` (the order of the field files).
* Velocities are the half-step velocities v^{n+1/2}; positions ``x`` are the end-of-step positions
  x^{n+1}. The velocity gradient L = sum_k (v_k - v_0) (x) grad N_k is taken on the mid-step
  configuration x^{n+1/2} = x^{n+1} - dt/2 v^{n+1/2}; the old stress is rotated by the Cayley
  (Hughes-Winget) rotation Q = (I - dt/2 W)^-1 (I + dt/2 W) = I + 2 (A + A^2) / (1 + |a|^2),
  A = dt/2 W with axial vector a. For an exact rigid rotation increment R this L is exactly
  skew and Q = R (Cayley transform): a rigid rotation leaves the stress exact for any step size.
* The internal force uses sigma^{n+1} - q I on x^{n+1} (one-point rule, exact for P1):
  f_k = V (sigma - q I) grad N_k = (sigma - q I) c_k / 6, c_k the cross products below.
* Critical step of a cell: (smallest altitude = 3 V / largest face area) / c_d, reduced for the
  bulk viscosity by sqrt(1 + xi^2) - xi exactly as in 2D.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from .element_math import (FM, P_B1, P_B2, P_BULK, P_G, P_H, P_K, P_R1, P_R2, P_RATE, P_RHO,
                           P_SY0, add_chunk_part, general_material, heated, rate_factor_at)
from .flow_curves import plastic_return
from .kernel_layout import P_T0

__all__ = ["tet_step", "tet_cell", "tet_chunk_scalar", "tet_chunk_size", "TET_CHUNK", "add_tet_forces",
           "store_tet_forces", "clear_tet_forces",
           "tet_critical_dt",
           "MODE_SOLID"]

#: the kernel's mode value (``prm[P_MODE]``) for 3D solids (2D modes are 0-2)
MODE_SOLID = 3
_NO_SHARED = np.zeros(0, np.uint8)  # the serial kernels flag no node (a constant in compiled code)
#: most cells per chunk of the 3D kernels (:func:`tet_chunk_size`)
TET_CHUNK = 65536


@numba.njit(cache=True)
def tet_chunk_size(nc):
    """Cells per chunk of a 3D body of ``nc`` cells: at most :data:`TET_CHUNK`, the chunks (all of
    one size but the last) a power of two in number. A function of ``nc`` alone, so that the serial
    and the threaded kernels (:mod:`.tet_threads`) cut the same chunks whatever the thread count."""
    k = 1
    while k * TET_CHUNK < nc:
        k *= 2
    return max(1, -(-nc // k))


@numba.njit(cache=True, inline="always", error_model="numpy", fastmath=FM)
def _cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@numba.njit(cache=True, inline="always", error_model="numpy", fastmath=FM)
def _norm2(ax, ay, az):
    return ax * ax + ay * ay + az * az


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def add_tet_forces(f_int, i0, i1, i2, i3, f1x, f1y, f1z, f2x, f2y, f2z, f3x, f3y, f3z):
    """Add a cell's nodal forces (f_1, f_2, f_3; f_0 = -(f_1 + f_2 + f_3)), N, to the rows
    ``i0..i3`` of ``f_int``."""
    f_int[i0, 0] -= f1x + f2x + f3x
    f_int[i0, 1] -= f1y + f2y + f3y
    f_int[i0, 2] -= f1z + f2z + f3z
    f_int[i1, 0] += f1x
    f_int[i1, 1] += f1y
    f_int[i1, 2] += f1z
    f_int[i2, 0] += f2x
    f_int[i2, 1] += f2y
    f_int[i2, 2] += f2z
    f_int[i3, 0] += f3x
    f_int[i3, 1] += f3y
    f_int[i3, 2] += f3z


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def store_tet_forces(f_int, fe, shared, e, i0, i1, i2, i3, f1x, f1y, f1z, f2x, f2y, f2z, f3x,
                     f3y, f3z):
    """:func:`add_tet_forces` for the threaded kernel (:mod:`.tet_threads`): the rows flagged in
    ``shared`` (nodes whose cells lie in more than one chunk) are not touched; if the cell has one,
    its forces are stored in ``fe[e]`` (12: f_1 + f_2 + f_3, subtracted at node 0, then f_1, f_2,
    f_3; N) for the gather, which repeats these operations in cell order."""
    h0 = shared[i0] != 0
    h1 = shared[i1] != 0
    h2 = shared[i2] != 0
    h3 = shared[i3] != 0
    if not (h0 or h1 or h2 or h3):
        add_tet_forces(f_int, i0, i1, i2, i3, f1x, f1y, f1z, f2x, f2y, f2z, f3x, f3y, f3z)
        return
    s0x = f1x + f2x + f3x
    s0y = f1y + f2y + f3y
    s0z = f1z + f2z + f3z
    fe[e, 0] = s0x
    fe[e, 1] = s0y
    fe[e, 2] = s0z
    fe[e, 3] = f1x
    fe[e, 4] = f1y
    fe[e, 5] = f1z
    fe[e, 6] = f2x
    fe[e, 7] = f2y
    fe[e, 8] = f2z
    fe[e, 9] = f3x
    fe[e, 10] = f3y
    fe[e, 11] = f3z
    if not h0:
        f_int[i0, 0] -= s0x
        f_int[i0, 1] -= s0y
        f_int[i0, 2] -= s0z
    if not h1:
        f_int[i1, 0] += f1x
        f_int[i1, 1] += f1y
        f_int[i1, 2] += f1z
    if not h2:
        f_int[i2, 0] += f2x
        f_int[i2, 1] += f2y
        f_int[i2, 2] += f2z
    if not h3:
        f_int[i3, 0] += f3x
        f_int[i3, 1] += f3y
        f_int[i3, 2] += f3z


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def clear_tet_forces(fe, shared, e, i0, i1, i2, i3):
    """The stored forces of an inverted cell ``e`` (none) for the threaded kernel's gather."""
    if shared[i0] != 0 or shared[i1] != 0 or shared[i2] != 0 or shared[i3] != 0:
        for r in range(12):
            fe[e, r] = 0.0


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def tet_step(cells, x, v, dt, prm, stress, eps_p, f_int, acc, work, temp):
    """Explicit update of all tetrahedra ``cells`` (same signature as
    :func:`.kernels.element_step`; ``work`` is not used), in chunks of
    :func:`tet_chunk_size` cells (:func:`tet_chunk_scalar`): the dissipation is summed per
    chunk in cell order, then over the chunks in order, as the threaded kernel
    (:mod:`.tet_threads`) does.

    Parameters
    ----------
    cells : int32 array (nc, 4)
        Node rows of each (positively oriented) tetrahedron.
    x : float64 array (N, 3)
        End-of-step positions x^{n+1}, m.
    v : float64 array (N, 3)
        Half-step velocities v^{n+1/2}, m/s.
    dt : float
        Step, s.
    prm : float64 array
        Kernel parameters (:func:`.kernels.pack_parameters` with mode :data:`MODE_SOLID`).
    stress : float64 array (nc, 6)
        Cauchy stress [xx, yy, zz, xy, yz, xz], Pa; updated in place to sigma^{n+1}.
    eps_p : float64 array (nc,)
        Equivalent plastic strain; updated in place.
    f_int : float64 array (N, 3)
        Internal nodal forces, N; contributions are *added* in cell order.
    acc : float64 array (3,)
        ``acc[0] += plastic dissipation (J)``, ``acc[1] += bulk-viscous dissipation (J)``;
        ``acc[2]`` is set to the first inverted cell index, or -1.
    work : float64 array
        Not used (the signature of :func:`.kernels.element_step`).
    temp : float64 array (nc,) or (0,)
        Temperature per cell, K, heated in place by the plastic work of a material with a
        specific heat; empty: none (:func:`.kernels.element_step`; both required, as there).

    Returns
    -------
    float
        Smallest element critical time step (CFL 1, with the bulk-viscosity reduction), s.
    """
    part = np.empty(4)
    no_fe = np.empty((0, 12))
    nc = cells.shape[0]
    dtmin = 1e300
    wp = 0.0
    wv = 0.0
    acc[2] = -1.0
    cs = tet_chunk_size(nc)
    for e0 in range(0, nc, cs):
        tet_chunk_scalar(cells, x, v, dt, prm, stress, eps_p, f_int, no_fe, _NO_SHARED, e0,
                         min(nc, e0 + cs), part, temp)
        dtmin, wp, wv, acc[2] = add_chunk_part(part, dtmin, wp, wv, acc[2])
    acc[0] += wp
    acc[1] += wv
    return dtmin


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def tet_cell(cells, x, v, dt, prm, stress, eps_p, temp, e, res):
    """The update of tetrahedron ``e`` (the arguments of :func:`tet_step`; ``temp`` the temperature per
    cell, K, or empty: the material's initial temperature): its stress, plastic strain and temperature
    updated in place; ``res`` (13,) receives the forces of its nodes 1-3 (N; node 0 takes minus their
    sum), its critical step (s), its plastic and bulk-viscous dissipation (J) and its status (1 done,
    0 inverted: nothing else is written). Any rate law and flow curve; shared by the scalar kernel and
    the vectorised one's cells that yield (:mod:`.tet_batch`)."""
    rho = prm[P_RHO]
    G = prm[P_G]
    K = prm[P_K]
    lam = K - 2.0 * G / 3.0
    sy0 = prm[P_SY0]
    H = prm[P_H]
    rid = int(prm[P_RATE])
    r1 = prm[P_R1]
    r2 = prm[P_R2]
    b1 = prm[P_B1]
    b2 = prm[P_B2]
    bulk = prm[P_BULK] > 0.0
    general = general_material(prm)
    has_t = temp.shape[0] > 0
    c = math.sqrt((K + 4.0 * G / 3.0) / rho)
    hdt = 0.5 * dt
    i0 = cells[e, 0]
    i1 = cells[e, 1]
    i2 = cells[e, 2]
    i3 = cells[e, 3]
    # velocities relative to node 0 (a rigid translation gives L = 0 exactly)
    u1x = v[i1, 0] - v[i0, 0]
    u1y = v[i1, 1] - v[i0, 1]
    u1z = v[i1, 2] - v[i0, 2]
    u2x = v[i2, 0] - v[i0, 0]
    u2y = v[i2, 1] - v[i0, 1]
    u2z = v[i2, 2] - v[i0, 2]
    u3x = v[i3, 0] - v[i0, 0]
    u3y = v[i3, 1] - v[i0, 1]
    u3z = v[i3, 2] - v[i0, 2]
    # edges on the end configuration
    ax = x[i1, 0] - x[i0, 0]
    ay = x[i1, 1] - x[i0, 1]
    az = x[i1, 2] - x[i0, 2]
    bx = x[i2, 0] - x[i0, 0]
    by = x[i2, 1] - x[i0, 1]
    bz = x[i2, 2] - x[i0, 2]
    cx = x[i3, 0] - x[i0, 0]
    cy = x[i3, 1] - x[i0, 1]
    cz = x[i3, 2] - x[i0, 2]
    # ... and on the mid-step configuration
    max_ = ax - hdt * u1x
    may = ay - hdt * u1y
    maz = az - hdt * u1z
    mbx = bx - hdt * u2x
    mby = by - hdt * u2y
    mbz = bz - hdt * u2z
    mcx = cx - hdt * u3x
    mcy = cy - hdt * u3y
    mcz = cz - hdt * u3z
    g1x, g1y, g1z = _cross(mbx, mby, mbz, mcx, mcy, mcz)
    g2x, g2y, g2z = _cross(mcx, mcy, mcz, max_, may, maz)
    g3x, g3y, g3z = _cross(max_, may, maz, mbx, mby, mbz)
    detm = max_ * g1x + may * g1y + maz * g1z
    n1x, n1y, n1z = _cross(bx, by, bz, cx, cy, cz)
    n2x, n2y, n2z = _cross(cx, cy, cz, ax, ay, az)
    n3x, n3y, n3z = _cross(ax, ay, az, bx, by, bz)
    detn = ax * n1x + ay * n1y + az * n1z
    if not (detm > 0.0 and detn > 0.0):
        res[12] = 0.0
        return
    inv = 1.0 / detm
    # L_ij = sum_k u_k,i g_k,j / det
    lxx = (u1x * g1x + u2x * g2x + u3x * g3x) * inv
    lxy = (u1x * g1y + u2x * g2y + u3x * g3y) * inv
    lxz = (u1x * g1z + u2x * g2z + u3x * g3z) * inv
    lyx = (u1y * g1x + u2y * g2x + u3y * g3x) * inv
    lyy = (u1y * g1y + u2y * g2y + u3y * g3y) * inv
    lyz = (u1y * g1z + u2y * g2z + u3y * g3z) * inv
    lzx = (u1z * g1x + u2z * g2x + u3z * g3x) * inv
    lzy = (u1z * g1y + u2z * g2y + u3z * g3y) * inv
    lzz = (u1z * g1z + u2z * g2z + u3z * g3z) * inv
    dxx = lxx
    dyy = lyy
    dzz = lzz
    dxy = 0.5 * (lxy + lyx)
    dyz = 0.5 * (lyz + lzy)
    dxz = 0.5 * (lxz + lzx)
    # Cayley rotation Q = I + k (A + A^2), A = dt/2 W (skew: a01, a02, a12 above the diagonal)
    a01 = hdt * 0.5 * (lxy - lyx)
    a02 = hdt * 0.5 * (lxz - lzx)
    a12 = hdt * 0.5 * (lyz - lzy)
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
    sxx = stress[e, 0]
    syy = stress[e, 1]
    szz = stress[e, 2]
    sxy = stress[e, 3]
    syz = stress[e, 4]
    sxz = stress[e, 5]
    # T = Q sigma
    t00 = q00 * sxx + q01 * sxy + q02 * sxz
    t01 = q00 * sxy + q01 * syy + q02 * syz
    t02 = q00 * sxz + q01 * syz + q02 * szz
    t10 = q10 * sxx + q11 * sxy + q12 * sxz
    t11 = q10 * sxy + q11 * syy + q12 * syz
    t12 = q10 * sxz + q11 * syz + q12 * szz
    t20 = q20 * sxx + q21 * sxy + q22 * sxz
    t21 = q20 * sxy + q21 * syy + q22 * syz
    t22 = q20 * sxz + q21 * syz + q22 * szz
    # R = T Q^T (symmetric)
    rxx = t00 * q00 + t01 * q01 + t02 * q02
    ryy = t10 * q10 + t11 * q11 + t12 * q12
    rzz = t20 * q20 + t21 * q21 + t22 * q22
    rxy = t00 * q10 + t01 * q11 + t02 * q12
    ryz = t10 * q20 + t11 * q21 + t12 * q22
    rxz = t00 * q20 + t01 * q21 + t02 * q22
    # elastic predictor + radial return
    trd = dxx + dyy + dzz
    mr = trd / 3.0
    ep = eps_p[e]
    rate = 0.0
    tc = 0.0
    sy = 0.0
    if general:
        rate = math.sqrt(2.0 / 3.0 * ((dxx - mr) ** 2 + (dyy - mr) ** 2 + (dzz - mr) ** 2
                                      + 2.0 * (dxy * dxy + dyz * dyz + dxz * dxz)))
        fac = rate_factor_at(rid, r1, r2, rate)
        tc = temp[e] if has_t else prm[P_T0]
        hr = 0.0
    else:
        fac = rate_factor_at(rid, r1, r2, math.sqrt(2.0 / 3.0 * (
            (dxx - mr) ** 2 + (dyy - mr) ** 2 + (dzz - mr) ** 2
            + 2.0 * (dxy * dxy + dyz * dyz + dxz * dxz)))) if rid != 0 else 1.0
        sy = (sy0 + H * ep) * fac
        hr = H * fac
    ltr = lam * trd * dt
    g2 = 2.0 * G * dt
    txx = rxx + ltr + g2 * dxx
    tyy = ryy + ltr + g2 * dyy
    tzz = rzz + ltr + g2 * dzz
    txy = rxy + g2 * dxy
    tyz = ryz + g2 * dyz
    txz = rxz + g2 * dxz
    p = (txx + tyy + tzz) / 3.0
    exx = txx - p
    eyy = tyy - p
    ezz = tzz - p
    qm = math.sqrt(1.5 * (exx * exx + eyy * eyy + ezz * ezz
                          + 2.0 * (txy * txy + tyz * tyz + txz * txz)))
    dep = 0.0
    if general:
        dep, sy = plastic_return(qm, G, ep, rate, tc, fac, prm)
        plastic = dep > 0.0
        if has_t:
            temp[e] = heated(tc, sy, dep, prm)
    else:
        plastic = qm > sy
        if plastic:
            dep = (qm - sy) / (3.0 * G + hr)
    if plastic:
        f = 1.0 - 3.0 * G * dep / qm
        txx = exx * f + p
        tyy = eyy * f + p
        tzz = ezz * f + p
        txy *= f
        tyz *= f
        txz *= f
    stress[e, 0] = txx
    stress[e, 1] = tyy
    stress[e, 2] = tzz
    stress[e, 3] = txy
    stress[e, 4] = tyz
    stress[e, 5] = txz
    eps_p[e] = ep + dep
    # critical step and bulk viscosity on the end configuration
    n0x = n1x + n2x + n3x
    n0y = n1y + n2y + n3y
    n0z = n1z + n2z + n3z
    amax = max(max(_norm2(n0x, n0y, n0z), _norm2(n1x, n1y, n1z)),
               max(_norm2(n2x, n2y, n2z), _norm2(n3x, n3y, n3z)))
    le = detn / math.sqrt(amax)
    q = 0.0
    xi = 0.0
    if bulk:
        q = b1 * rho * c * le * (-trd)
        xi = b1
        if trd < 0.0:
            q += rho * (b2 * le * trd) ** 2
            xi += b2 * b2 * le / c * (-trd)
    res[9] = le / c * (math.sqrt(1.0 + xi * xi) - xi)
    volm = detm / 6.0
    res[10] = (sy + hr * dep) * dep * volm
    res[11] = -q * trd * volm * dt
    # nodal forces f_k = (sigma - q I) n_k / 6 (k = 1..3), f_0 = -(f_1 + f_2 + f_3)
    sx = (txx - q) / 6.0
    sy_ = (tyy - q) / 6.0
    sz = (tzz - q) / 6.0
    sxy6 = txy / 6.0
    syz6 = tyz / 6.0
    sxz6 = txz / 6.0
    f1x = sx * n1x + sxy6 * n1y + sxz6 * n1z
    f1y = sxy6 * n1x + sy_ * n1y + syz6 * n1z
    f1z = sxz6 * n1x + syz6 * n1y + sz * n1z
    f2x = sx * n2x + sxy6 * n2y + sxz6 * n2z
    f2y = sxy6 * n2x + sy_ * n2y + syz6 * n2z
    f2z = sxz6 * n2x + syz6 * n2y + sz * n2z
    f3x = sx * n3x + sxy6 * n3y + sxz6 * n3z
    f3y = sxy6 * n3x + sy_ * n3y + syz6 * n3z
    f3z = sxz6 * n3x + syz6 * n3y + sz * n3z
    res[0] = f1x
    res[1] = f1y
    res[2] = f1z
    res[3] = f2x
    res[4] = f2y
    res[5] = f2z
    res[6] = f3x
    res[7] = f3y
    res[8] = f3z
    res[12] = 1.0


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def tet_chunk_scalar(cells, x, v, dt, prm, stress, eps_p, f_int, fe, shared, e0, e1, part, temp):
    """Cells ``e0:e1`` of :func:`tet_step` (the scalar kernel, any rate law and flow curve; ``temp``
    the temperature per cell, K, or empty: the material's initial temperature), each by
    :func:`tet_cell`: the arguments of :func:`tet_step`; the nodal forces are added to ``f_int``
    (:func:`add_tet_forces`), or, if ``fe`` has rows (the threaded kernel), by
    :func:`store_tet_forces` with ``shared``; ``part`` (4,) receives (smallest critical step s,
    plastic and bulk-viscous dissipation J summed in cell order, first inverted cell or -1). An
    inverted cell keeps its stress and plastic strain and gives no force."""
    res = np.empty(13)
    dtmin = 1e300
    wp = 0.0
    wv = 0.0
    bad = -1.0
    store = fe.shape[0] > 0
    for e in range(e0, e1):
        tet_cell(cells, x, v, dt, prm, stress, eps_p, temp, e, res)
        i0 = cells[e, 0]
        i1 = cells[e, 1]
        i2 = cells[e, 2]
        i3 = cells[e, 3]
        if res[12] == 0.0:
            if bad < 0.0:
                bad = e
            if store:
                clear_tet_forces(fe, shared, e, i0, i1, i2, i3)
            continue
        if res[9] < dtmin:
            dtmin = res[9]
        wp += res[10]
        wv += res[11]
        if store:
            store_tet_forces(f_int, fe, shared, e, i0, i1, i2, i3, res[0], res[1], res[2], res[3], res[4],
                             res[5], res[6], res[7], res[8])
        else:
            add_tet_forces(f_int, i0, i1, i2, i3, res[0], res[1], res[2], res[3], res[4], res[5], res[6],
                           res[7], res[8])
    part[0] = dtmin
    part[1] = wp
    part[2] = wv
    part[3] = bad


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def tet_critical_dt(cells, x, prm):
    """Smallest element critical time step (CFL 1, at rest: the linear bulk-viscosity reduction
    only), s; -1.0 if any cell is inverted (non-positive volume)."""
    c = math.sqrt((prm[P_K] + 4.0 * prm[P_G] / 3.0) / prm[P_RHO])
    xi = prm[P_B1] if prm[P_BULK] > 0.0 else 0.0
    red = math.sqrt(1.0 + xi * xi) - xi
    dtmin = 1e300
    for e in range(cells.shape[0]):
        i0 = cells[e, 0]
        ax = x[cells[e, 1], 0] - x[i0, 0]
        ay = x[cells[e, 1], 1] - x[i0, 1]
        az = x[cells[e, 1], 2] - x[i0, 2]
        bx = x[cells[e, 2], 0] - x[i0, 0]
        by = x[cells[e, 2], 1] - x[i0, 1]
        bz = x[cells[e, 2], 2] - x[i0, 2]
        cx = x[cells[e, 3], 0] - x[i0, 0]
        cy = x[cells[e, 3], 1] - x[i0, 1]
        cz = x[cells[e, 3], 2] - x[i0, 2]
        n1x, n1y, n1z = _cross(bx, by, bz, cx, cy, cz)
        n2x, n2y, n2z = _cross(cx, cy, cz, ax, ay, az)
        n3x, n3y, n3z = _cross(ax, ay, az, bx, by, bz)
        det = ax * n1x + ay * n1y + az * n1z
        if det <= 0.0:
            return -1.0
        amax = max(max(_norm2(n1x + n2x + n3x, n1y + n2y + n3y, n1z + n2z + n3z),
                       _norm2(n1x, n1y, n1z)), max(_norm2(n2x, n2y, n2z), _norm2(n3x, n3y, n3z)))
        dte = det / math.sqrt(amax) / c * red
        if dte < dtmin:
            dtmin = dte
    return dtmin
