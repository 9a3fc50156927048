"""The stress update of one 2D point, compiled (numba): the Hughes-Winget rotation of the old stress, the
hypo-elastic predictor, the J2 radial return with the linear law or any flow curve (:mod:`.flow_curves`) and the
rate laws, adiabatic heating, and the plane-stress secant iteration — for a linear triangle
(:func:`.element_math.cell_update`) and for each Gauss point of a six-node one (:mod:`.tri6_kernel`); the rate
laws and the heating serve the 3D kernels too. Voigt stress ``[xx, yy, zz, xy]``, rates of deformation in 1/s.
"""
from __future__ import annotations

import math

import numba

from .flow_curves import plastic_return
from .kernel_layout import FM, P_BETA, P_FLOW, P_G, P_H, P_K, P_MODE, P_R1, P_R2, P_RATE, P_RHOCP, P_SY0, P_T0, P_THERM

__all__ = ["MODE_PLANE_STRESS", "MODE_PLANE_STRAIN", "MODE_AXISYMMETRIC", "rate_factor", "rate_factor_at",
           "elastic_trial", "j2_return", "equivalent_rate", "j2_return_flow", "general_material", "heated",
           "point_update"]

MODE_PLANE_STRESS = 0
MODE_PLANE_STRAIN = 1
MODE_AXISYMMETRIC = 2


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def rate_factor(rid, r1, r2, dxx, dyy, dzz, dxy):
    """Yield-stress factor of the rate law ``rid`` (0 none, 1 Cowper-Symonds, 2 Johnson-Cook) at
    the rate of deformation d (1/s)."""
    if rid == 0:
        return 1.0
    m = (dxx + dyy + dzz) / 3.0
    exx, eyy, ezz = dxx - m, dyy - m, dzz - m
    rate = math.sqrt(2.0 / 3.0 * (exx * exx + eyy * eyy + ezz * ezz + 2.0 * dxy * dxy))
    return rate_factor_at(rid, r1, r2, rate)


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def rate_factor_at(rid, r1, r2, rate):
    """Yield-stress factor of the rate law ``rid`` (0 none, 1 Cowper-Symonds, 2 Johnson-Cook) at
    the equivalent strain rate ``rate`` = sqrt(2/3 e:e) (1/s), e the deviatoric rate of deformation
    (shared by the 2D and the 3D kernels)."""
    if rid == 0:
        return 1.0
    if rid == 1:
        return 1.0 + (rate / r1) ** (1.0 / r2)
    if rate > r2:
        return 1.0 + r1 * math.log(rate / r2)
    return 1.0


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def elastic_trial(sxx, syy, szz, sxy, dxx, dyy, dzz, dxy, dt, G, lam):
    """Elastic predictor of a step (Pa, 1/s, s): the trial stress (txx, tyy, tzz, txy), its pressure p, its
    deviator (exx, eyy, ezz; the shear is txy) and its von Mises stress q, Pa."""
    tr = (dxx + dyy + dzz) * dt
    txx = sxx + lam * tr + 2.0 * G * dxx * dt
    tyy = syy + lam * tr + 2.0 * G * dyy * dt
    tzz = szz + lam * tr + 2.0 * G * dzz * dt
    txy = sxy + 2.0 * G * dxy * dt
    p = (txx + tyy + tzz) / 3.0
    exx, eyy, ezz = txx - p, tyy - p, tzz - p
    q = math.sqrt(1.5 * (exx * exx + eyy * eyy + ezz * ezz + 2.0 * txy * txy))
    return txx, tyy, tzz, txy, p, exx, eyy, ezz, q


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def j2_return(sxx, syy, szz, sxy, dxx, dyy, dzz, dxy, dt, G, lam, sy, hr):
    """Elastic predictor + radial return (Pa, 1/s, s). Returns (sxx, syy, szz, sxy, deps_p)."""
    txx, tyy, tzz, txy, p, exx, eyy, ezz, q = elastic_trial(sxx, syy, szz, sxy, dxx, dyy, dzz, dxy, dt, G, lam)
    if q > sy:
        dep = (q - sy) / (3.0 * G + hr)
        fac = 1.0 - 3.0 * G * dep / q
        return exx * fac + p, eyy * fac + p, ezz * fac + p, txy * fac, dep
    return txx, tyy, tzz, txy, 0.0


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def equivalent_rate(dxx, dyy, dzz, dxy):
    """Equivalent strain rate sqrt(2/3 e:e) (1/s) of the rate of deformation d (1/s), e its
    deviator."""
    m = (dxx + dyy + dzz) / 3.0
    exx, eyy, ezz = dxx - m, dyy - m, dzz - m
    return math.sqrt(2.0 / 3.0 * (exx * exx + eyy * eyy + ezz * ezz + 2.0 * dxy * dxy))


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def j2_return_flow(sxx, syy, szz, sxy, dxx, dyy, dzz, dxy, dt, G, lam, ep, rate, T, fac, prm):
    """:func:`j2_return` for any flow curve (:mod:`.flow_curves`) at the plastic strain ``ep``, the
    equivalent strain rate ``rate`` (1/s) and the temperature ``T`` (K), times the rate law's
    factor ``fac``. Returns (sxx, syy, szz, sxy, deps_p, yield stress after the return (Pa))."""
    txx, tyy, tzz, txy, p, exx, eyy, ezz, q = elastic_trial(sxx, syy, szz, sxy, dxx, dyy, dzz, dxy, dt, G, lam)
    dep, sy = plastic_return(q, G, ep, rate, T, fac, prm)
    if dep > 0.0:
        f = 1.0 - 3.0 * G * dep / q
        return exx * f + p, eyy * f + p, ezz * f + p, txy * f, dep, sy
    return txx, tyy, tzz, txy, 0.0, sy


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def general_material(prm):
    """Whether the material needs the general return (a flow curve other than the linear law, or
    a temperature per cell): the vectorised kernels then only screen for elastic cells."""
    return prm[P_FLOW] != 0.0 or prm[P_THERM] != 0.0


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def heated(T, sy, dep, prm):
    """Temperature (K) after the adiabatic plastic heating rho c_p dT = beta sy dep (sy: yield
    stress after the return, Pa; dep: plastic strain increment) of a cell at ``T``."""
    if prm[P_THERM] != 0.0:
        return T + prm[P_BETA] * sy * dep / prm[P_RHOCP]
    return T


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def point_update(sxx, syy, szz, sxy, ep, T, dxx, dyy, dzz, dxy, w, dt, prm):
    """The stress update of one 2D point (a linear triangle, or a Gauss point of a six-node one): the
    Hughes-Winget rotation of the old stress (Pa) by the spin ``w`` (1/s), the elastic predictor with the rate
    of deformation (dxx, dyy, dzz, dxy) (1/s; dzz the hoop rate in axisymmetry, 0 in plane strain, the elastic
    estimate in plane stress), the J2 return at the plastic strain ``ep`` and temperature ``T`` (K, negative:
    the material's initial one), and in plane stress the secant iteration on d_zz so that sigma_zz = 0 after
    the return. Returns (sxx, syy, szz, sxy, deps_p, yield stress (Pa), hardening (Pa) of the linear law's
    dissipation, the final dzz (1/s))."""
    G = prm[P_G]
    K = prm[P_K]
    lam = K - 2.0 * G / 3.0
    sy0 = prm[P_SY0]
    H = prm[P_H]
    rid = int(prm[P_RATE])
    r1 = prm[P_R1]
    r2 = prm[P_R2]
    mode = int(prm[P_MODE])
    hdt = 0.5 * dt
    # Hughes-Winget (Cayley) rotation of the old stress: Jaumann objective update
    a = hdt * w
    den = 1.0 / (1.0 + a * a)
    cs = (1.0 - a * a) * den
    sn = 2.0 * a * den
    rxx = cs * cs * sxx + 2.0 * cs * sn * sxy + sn * sn * syy
    ryy = sn * sn * sxx - 2.0 * cs * sn * sxy + cs * cs * syy
    rxy = -cs * sn * sxx + (cs * cs - sn * sn) * sxy + cs * sn * syy
    general = general_material(prm)
    if T < 0.0:
        T = prm[P_T0]
    if general:
        rate = equivalent_rate(dxx, dyy, dzz, dxy)
        fac = rate_factor_at(rid, r1, r2, rate)
        hr = 0.0
        nxx, nyy, nzz, nxy, dep, sy = j2_return_flow(rxx, ryy, szz, rxy, dxx, dyy, dzz, dxy, dt, G,
                                                     lam, ep, rate, T, fac, prm)
    else:
        fac = rate_factor(rid, r1, r2, dxx, dyy, dzz, dxy)
        sy = (sy0 + H * ep) * fac
        hr = H * fac
        nxx, nyy, nzz, nxy, dep = j2_return(rxx, ryy, szz, rxy, dxx, dyy, dzz, dxy, dt, G, lam, sy, hr)
    if mode == MODE_PLANE_STRESS:
        tol = 1e-12 * (sy + abs(nxx) + abs(nyy))
        if dep > 0.0 and abs(nzz) > tol:
            # secant iteration on d_zz so that sigma_zz = 0 after the return
            z0 = dzz
            r0 = nzz
            z1 = dzz - nzz / ((lam + 2.0 * G) * dt)
            for _it in range(30):
                if general:
                    rate = equivalent_rate(dxx, dyy, z1, dxy)
                    fac = rate_factor_at(rid, r1, r2, rate)
                    nxx, nyy, nzz, nxy, dep, sy = j2_return_flow(rxx, ryy, szz, rxy, dxx, dyy, z1, dxy,
                                                                 dt, G, lam, ep, rate, T, fac, prm)
                else:
                    fac = rate_factor(rid, r1, r2, dxx, dyy, z1, dxy)
                    sy = (sy0 + H * ep) * fac
                    hr = H * fac
                    nxx, nyy, nzz, nxy, dep = j2_return(rxx, ryy, szz, rxy, dxx, dyy, z1, dxy, dt, G,
                                                        lam, sy, hr)
                if abs(nzz) <= tol or nzz == r0:
                    break
                z2 = z1 - nzz * (z1 - z0) / (nzz - r0)
                z0 = z1
                r0 = nzz
                z1 = z2
            dzz = z1
        nzz = 0.0
    return nxx, nyy, nzz, nxy, dep, sy, hr, dzz
