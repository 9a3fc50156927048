"""Compiled (numba) element kernel of the explicit step: objective stress update, J2 radial return,
bulk viscosity, internal nodal forces and element critical time steps, fused in one pass over cells.

Conventions
-----------
* Cells are triangles given by three local node (row) indices into the nodal arrays.
* Stress per cell in Voigt order ``[xx, yy, zz, xy]``; ``zz`` is the hoop stress in axisymmetry
  (x = r, y = z) and the out-of-plane stress in plane strain (it is kept at zero in plane stress).
* Velocities are the half-step velocities v^{n+1/2}; positions ``x`` are the end-of-step positions
  x^{n+1}. The velocity gradient is evaluated on the mid-step configuration
  x^{n+1/2} = x^{n+1} - dt/2 v^{n+1/2}; with the Hughes-Winget rotation this makes a rigid rotation
  stress-free *exactly* (Cayley transform), for any step size.
* The internal force is evaluated with sigma^{n+1} on x^{n+1} (one-point rule, hoop term at the
  centroid in axisymmetry) and *added* to ``f_int``.
"""
from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["MODE_PLANE_STRESS", "MODE_PLANE_STRAIN", "MODE_AXISYMMETRIC", "pack_parameters",
           "element_step", "element_critical_dt", "N_PRM"]

# fast-math without 'nnan'/'ninf', so that NaN/inf checks (inverted cells, blow-ups) still work
_FM = {"contract", "arcp", "reassoc", "nsz"}

MODE_PLANE_STRESS = 0
MODE_PLANE_STRAIN = 1
MODE_AXISYMMETRIC = 2

# parameter vector layout
P_RHO, P_G, P_K, P_SY0, P_H, P_RATE, P_R1, P_R2, P_B1, P_B2, P_BULK, P_THICK, P_MODE = range(13)
N_PRM = 13


def pack_parameters(material, mode: int, thickness: float, b1: float, b2: float,
                    bulk_viscosity: bool) -> np.ndarray:
    """Pack a :class:`~.material.Material` and options into the kernel's float64 parameter vector.

    Parameters
    ----------
    material : Material
        Material of the body.
    mode : int
        One of ``MODE_PLANE_STRESS``, ``MODE_PLANE_STRAIN``, ``MODE_AXISYMMETRIC``.
    thickness : float
        Out-of-plane thickness, m (ignored in axisymmetry).
    b1, b2 : float
        Linear and quadratic bulk-viscosity coefficients (dimensionless).
    bulk_viscosity : bool
        Whether bulk viscosity is active.
    """
    rid, r1, r2 = material.rate_parameters()
    prm = np.zeros(N_PRM)
    prm[P_RHO] = material.density
    prm[P_G] = material.shear_modulus
    prm[P_K] = material.bulk_modulus
    prm[P_SY0] = material.yield_stress
    prm[P_H] = material.hardening_modulus
    prm[P_RATE], prm[P_R1], prm[P_R2] = rid, r1, r2
    prm[P_B1], prm[P_B2] = b1, b2
    prm[P_BULK] = 1.0 if bulk_viscosity else 0.0
    prm[P_THICK] = thickness
    prm[P_MODE] = mode
    return prm


@numba.njit(cache=True, inline="always", error_model="numpy", fastmath=_FM)
def _rate_factor(rid, r1, r2, dxx, dyy, dzz, dxy):
    if rid == 0:
        return 1.0
    m = (dxx + dyy + dzz) / 3.0
    exx, eyy, ezz = dxx - m, dyy - m, dzz - m
    rate = math.sqrt(2.0 / 3.0 * (exx * exx + eyy * eyy + ezz * ezz + 2.0 * dxy * dxy))
    if rid == 1:
        return 1.0 + (rate / r1) ** (1.0 / r2)
    if rate > r2:
        return 1.0 + r1 * math.log(rate / r2)
    return 1.0


@numba.njit(cache=True, inline="always", error_model="numpy", fastmath=_FM)
def _j2(sxx, syy, szz, sxy, dxx, dyy, dzz, dxy, dt, G, lam, sy, hr):
    """Elastic predictor + radial return. Returns (sxx, syy, szz, sxy, deps_p)."""
    tr = (dxx + dyy + dzz) * dt
    txx = sxx + lam * tr + 2.0 * G * dxx * dt
    tyy = syy + lam * tr + 2.0 * G * dyy * dt
    tzz = szz + lam * tr + 2.0 * G * dzz * dt
    txy = sxy + 2.0 * G * dxy * dt
    p = (txx + tyy + tzz) / 3.0
    exx, eyy, ezz = txx - p, tyy - p, tzz - p
    q = math.sqrt(1.5 * (exx * exx + eyy * eyy + ezz * ezz + 2.0 * txy * txy))
    if q > sy:
        dep = (q - sy) / (3.0 * G + hr)
        fac = 1.0 - 3.0 * G * dep / q
        return exx * fac + p, eyy * fac + p, ezz * fac + p, txy * fac, dep
    return txx, tyy, tzz, txy, 0.0


@numba.njit(cache=True, error_model="numpy", fastmath=_FM)
def element_step(cells, x, v, dt, prm, stress, eps_p, f_int, acc):
    """Fused explicit element update over all ``cells``.

    Parameters
    ----------
    cells : int32 array (nc, 3)
        Node rows of each triangle.
    x : float64 array (N, 2)
        End-of-step positions x^{n+1}, m.
    v : float64 array (N, 2)
        Half-step velocities v^{n+1/2}, m/s.
    dt : float
        Step, s.
    prm : float64 array (N_PRM,)
        See :func:`pack_parameters`.
    stress : float64 array (nc, 4)
        Cauchy stress, Pa; updated in place to sigma^{n+1}.
    eps_p : float64 array (nc,)
        Equivalent plastic strain; updated in place.
    f_int : float64 array (N, 2)
        Internal nodal forces, N; contributions are *added*.
    acc : float64 array (3,)
        ``acc[0] += plastic dissipation (J)``, ``acc[1] += bulk-viscous dissipation (J)``;
        ``acc[2]`` is set to the first inverted cell index, or -1.

    Returns
    -------
    float
        Smallest element critical time step (CFL 1, with the bulk-viscosity reduction), s.
    """
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
    bulk = prm[P_BULK]
    thick = prm[P_THICK]
    mode = int(prm[P_MODE])
    c = math.sqrt((K + 4.0 * G / 3.0) / rho)
    twopi = 2.0 * math.pi
    dtmin = 1e300
    acc[2] = -1.0
    hdt = 0.5 * dt
    wp = 0.0
    wv = 0.0
    for e in range(cells.shape[0]):
        i0 = cells[e, 0]
        i1 = cells[e, 1]
        i2 = cells[e, 2]
        vx0 = v[i0, 0]
        vy0 = v[i0, 1]
        vx1 = v[i1, 0]
        vy1 = v[i1, 1]
        vx2 = v[i2, 0]
        vy2 = v[i2, 1]
        x0 = x[i0, 0]
        y0 = x[i0, 1]
        x1 = x[i1, 0]
        y1 = x[i1, 1]
        x2 = x[i2, 0]
        y2 = x[i2, 1]
        # mid-step configuration
        mx0 = x0 - hdt * vx0
        my0 = y0 - hdt * vy0
        mx1 = x1 - hdt * vx1
        my1 = y1 - hdt * vy1
        mx2 = x2 - hdt * vx2
        my2 = y2 - hdt * vy2
        ta = (mx1 - mx0) * (my2 - my0) - (mx2 - mx0) * (my1 - my0)
        tn = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if ta <= 0.0 or tn <= 0.0:
            if acc[2] < 0.0:
                acc[2] = e
            continue
        inv = 1.0 / ta
        bx0 = (my1 - my2) * inv
        bx1 = (my2 - my0) * inv
        bx2 = (my0 - my1) * inv
        by0 = (mx2 - mx1) * inv
        by1 = (mx0 - mx2) * inv
        by2 = (mx1 - mx0) * inv
        lxx = vx0 * bx0 + vx1 * bx1 + vx2 * bx2
        lxy = vx0 * by0 + vx1 * by1 + vx2 * by2
        lyx = vy0 * bx0 + vy1 * bx1 + vy2 * bx2
        lyy = vy0 * by0 + vy1 * by1 + vy2 * by2
        dxx = lxx
        dyy = lyy
        dxy = 0.5 * (lxy + lyx)
        w = 0.5 * (lxy - lyx)
        if mode == MODE_AXISYMMETRIC:
            rm = (mx0 + mx1 + mx2) / 3.0
            dzz = (vx0 + vx1 + vx2) / (3.0 * rm)
        elif mode == MODE_PLANE_STRAIN:
            dzz = 0.0
        else:
            dzz = -lam / (lam + 2.0 * G) * (dxx + dyy)
        # Hughes-Winget (Cayley) rotation of the old stress: Jaumann objective update
        a = hdt * w
        den = 1.0 / (1.0 + a * a)
        cs = (1.0 - a * a) * den
        sn = 2.0 * a * den
        sxx = stress[e, 0]
        syy = stress[e, 1]
        szz = stress[e, 2]
        sxy = stress[e, 3]
        rxx = cs * cs * sxx + 2.0 * cs * sn * sxy + sn * sn * syy
        ryy = sn * sn * sxx - 2.0 * cs * sn * sxy + cs * cs * syy
        rxy = -cs * sn * sxx + (cs * cs - sn * sn) * sxy + cs * sn * syy
        fac = _rate_factor(rid, r1, r2, dxx, dyy, dzz, dxy)
        ep = eps_p[e]
        sy = (sy0 + H * ep) * fac
        hr = H * fac
        nxx, nyy, nzz, nxy, dep = _j2(rxx, ryy, szz, rxy, dxx, dyy, dzz, dxy, dt, G, lam, sy, hr)
        if mode == MODE_PLANE_STRESS:
            tol = 1e-12 * (sy + abs(nxx) + abs(nyy))
            if dep > 0.0 and abs(nzz) > tol:
                # secant iteration on d_zz so that sigma_zz = 0 after the return
                z0 = dzz
                r0 = nzz
                z1 = dzz - nzz / ((lam + 2.0 * G) * dt)
                for _it in range(30):
                    fac = _rate_factor(rid, r1, r2, dxx, dyy, z1, dxy)
                    sy = (sy0 + H * ep) * fac
                    hr = H * fac
                    nxx, nyy, nzz, nxy, dep = _j2(rxx, ryy, szz, rxy, dxx, dyy, z1, dxy, dt, G, lam,
                                                  sy, hr)
                    if abs(nzz) <= tol or nzz == r0:
                        break
                    z2 = z1 - nzz * (z1 - z0) / (nzz - r0)
                    z0 = z1
                    r0 = nzz
                    z1 = z2
                dzz = z1
            nzz = 0.0
        stress[e, 0] = nxx
        stress[e, 1] = nyy
        stress[e, 2] = nzz
        stress[e, 3] = nxy
        eps_p[e] = ep + dep
        # geometry at the end of the step
        l01 = (x1 - x0) * (x1 - x0) + (y1 - y0) * (y1 - y0)
        l12 = (x2 - x1) * (x2 - x1) + (y2 - y1) * (y2 - y1)
        l20 = (x0 - x2) * (x0 - x2) + (y0 - y2) * (y0 - y2)
        lmax = math.sqrt(max(l01, max(l12, l20)))
        le = tn / lmax
        trd = dxx + dyy + dzz
        q = 0.0
        xi = 0.0
        if bulk > 0.0:
            q = b1 * rho * c * le * (-trd)
            xi = b1
            if trd < 0.0:
                q += rho * (b2 * le * trd) ** 2
                xi += b2 * b2 * le / c * (-trd)
        dte = le / c * (math.sqrt(1.0 + xi * xi) - xi)
        if dte < dtmin:
            dtmin = dte
        # volumes (mid for dissipation, end for forces)
        if mode == MODE_AXISYMMETRIC:
            volm = twopi * (mx0 + mx1 + mx2) / 3.0 * 0.5 * ta
            vol = twopi * (x0 + x1 + x2) / 3.0 * 0.5 * tn
        else:
            volm = thick * 0.5 * ta
            vol = thick * 0.5 * tn
        wp += (sy + hr * dep) * dep * volm
        if mode == MODE_PLANE_STRESS:
            wv -= q * (dxx + dyy) * volm * dt
        else:
            wv -= q * trd * volm * dt
        exx = nxx - q
        eyy = nyy - q
        ezz = nzz - q
        inv = vol / tn
        # d N / dx * vol, d N / dy * vol on the end configuration
        gx0 = (y1 - y2) * inv
        gx1 = (y2 - y0) * inv
        gx2 = (y0 - y1) * inv
        gy0 = (x2 - x1) * inv
        gy1 = (x0 - x2) * inv
        gy2 = (x1 - x0) * inv
        f_int[i0, 0] += exx * gx0 + nxy * gy0
        f_int[i0, 1] += nxy * gx0 + eyy * gy0
        f_int[i1, 0] += exx * gx1 + nxy * gy1
        f_int[i1, 1] += nxy * gx1 + eyy * gy1
        f_int[i2, 0] += exx * gx2 + nxy * gy2
        f_int[i2, 1] += nxy * gx2 + eyy * gy2
        if mode == MODE_AXISYMMETRIC:
            hoop = twopi * 0.5 * tn * ezz / 3.0
            f_int[i0, 0] += hoop
            f_int[i1, 0] += hoop
            f_int[i2, 0] += hoop
    acc[0] += wp
    acc[1] += wv
    return dtmin


@numba.njit(cache=True, error_model="numpy", fastmath=_FM)
def element_critical_dt(cells, x, prm):
    """Smallest element critical time step (CFL 1, at rest: linear bulk-viscosity reduction only), s.

    Also returns -1.0 if any cell is inverted (non-positive area).
    """
    G = prm[P_G]
    K = prm[P_K]
    c = math.sqrt((K + 4.0 * G / 3.0) / prm[P_RHO])
    xi = prm[P_B1] if prm[P_BULK] > 0.0 else 0.0
    red = math.sqrt(1.0 + xi * xi) - xi
    dtmin = 1e300
    for e in range(cells.shape[0]):
        i0 = cells[e, 0]
        i1 = cells[e, 1]
        i2 = cells[e, 2]
        x0 = x[i0, 0]
        y0 = x[i0, 1]
        x1 = x[i1, 0]
        y1 = x[i1, 1]
        x2 = x[i2, 0]
        y2 = x[i2, 1]
        tn = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if tn <= 0.0:
            return -1.0
        l01 = (x1 - x0) ** 2 + (y1 - y0) ** 2
        l12 = (x2 - x1) ** 2 + (y2 - y1) ** 2
        l20 = (x0 - x2) ** 2 + (y0 - y2) ** 2
        le = tn / math.sqrt(max(l01, max(l12, l20)))
        dte = le / c * red
        if dte < dtmin:
            dtmin = dte
    return dtmin
