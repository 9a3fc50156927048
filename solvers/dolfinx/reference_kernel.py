"""Plain vectorised-numpy version of :func:`.kernels.element_step` (gather, element-wise array
arithmetic — faster here than einsum over the small axes — and np.bincount scatter).

Same algorithm as the compiled kernel; it exists as a cross-check and as the benchmark baseline.
Only rate-independent materials are supported here.
"""
from __future__ import annotations

import numpy as np

from .kernel_layout import P_FLOW, P_THERM
from .kernels import (MODE_AXISYMMETRIC, MODE_PLANE_STRAIN, MODE_PLANE_STRESS, P_B1, P_B2, P_BULK,
                      P_G, P_H, P_K, P_MODE, P_RATE, P_RHO, P_SY0, P_THICK)

__all__ = ["element_step_numpy"]


def _j2(s, d, dt, G, lam, sy, hr):
    """Vectorised predictor + radial return; s, d: (n, 4) [xx, yy, zz, xy]."""
    tr = (d[:, 0] + d[:, 1] + d[:, 2]) * dt
    t = s + 2.0 * G * dt * d
    t[:, :3] += (lam * tr)[:, None]
    p = (t[:, 0] + t[:, 1] + t[:, 2]) / 3.0
    dev = t.copy()
    dev[:, :3] -= p[:, None]
    q = np.sqrt(1.5 * (dev[:, 0] ** 2 + dev[:, 1] ** 2 + dev[:, 2] ** 2 + 2.0 * dev[:, 3] ** 2))
    dep = np.where(q > sy, (q - sy) / (3.0 * G + hr), 0.0)
    fac = np.where(q > sy, 1.0 - 3.0 * G * dep / np.where(q > 0, q, 1.0), 1.0)
    out = dev * fac[:, None]
    out[:, :3] += p[:, None]
    return out, dep


def _grads(X):
    """Twice the area (n,) and area-scaled shape-function gradients gx, gy (3, n) of the
    triangles X (2, 3, n)."""
    x0, x1, x2 = X[0]
    y0, y1, y2 = X[1]
    ta = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    gx = np.stack([y1 - y2, y2 - y0, y0 - y1])
    gy = np.stack([x2 - x1, x0 - x2, x1 - x0])
    return ta, gx, gy


def element_step_numpy(cells, x, v, dt, prm, stress, eps_p, f_int, acc, work=None, temp=None):
    """Vectorised-numpy twin of :func:`.kernels.element_step` (same arguments and return value;
    ``work`` and ``temp`` are not used: the linear law without temperature only)."""
    if int(prm[P_RATE]) != 0:
        raise NotImplementedError("the numpy reference kernel supports rate-independent materials")
    if prm[P_FLOW] != 0 or prm[P_THERM] != 0:
        raise NotImplementedError("the numpy reference kernel supports the linear law without temperature")
    rho, G, K = prm[P_RHO], prm[P_G], prm[P_K]
    lam = K - 2.0 * G / 3.0
    mode = int(prm[P_MODE])
    c = np.sqrt((K + 4.0 * G / 3.0) / rho)
    n = cells.shape[0]
    ct = np.ascontiguousarray(cells.T)                  # (3, n)
    X = np.ascontiguousarray(x.T)[:, ct]                # (2, 3, n) gather, contiguous per node
    V = np.ascontiguousarray(v.T)[:, ct]
    XM = X - 0.5 * dt * V
    acc[2] = -1.0
    ta, gmx, gmy = _grads(XM)
    tn, gnx, gny = _grads(X)
    bad = (ta <= 0) | (tn <= 0)
    if bad.any():
        acc[2] = float(np.flatnonzero(bad)[0])
    ta = np.where(bad, 1.0, ta)
    tn = np.where(bad, 1.0, tn)
    inv = 1.0 / ta
    vx, vy = V[0], V[1]
    # L[i, j] = d v_i / d x_j = sum_a v_ai g_aj / (2 area)
    lxx = (vx[0] * gmx[0] + vx[1] * gmx[1] + vx[2] * gmx[2]) * inv
    lxy = (vx[0] * gmy[0] + vx[1] * gmy[1] + vx[2] * gmy[2]) * inv
    lyx = (vy[0] * gmx[0] + vy[1] * gmx[1] + vy[2] * gmx[2]) * inv
    lyy = (vy[0] * gmy[0] + vy[1] * gmy[1] + vy[2] * gmy[2]) * inv
    d = np.empty((n, 4))
    d[:, 0] = lxx
    d[:, 1] = lyy
    d[:, 3] = 0.5 * (lxy + lyx)
    w = 0.5 * (lxy - lyx)
    rm = (XM[0, 0] + XM[0, 1] + XM[0, 2]) / 3.0
    if mode == MODE_AXISYMMETRIC:
        d[:, 2] = (vx[0] + vx[1] + vx[2]) / (3.0 * rm)
    elif mode == MODE_PLANE_STRAIN:
        d[:, 2] = 0.0
    else:
        d[:, 2] = -lam / (lam + 2.0 * G) * (d[:, 0] + d[:, 1])
    a = 0.5 * dt * w
    den = 1.0 / (1.0 + a * a)
    cs, sn = (1.0 - a * a) * den, 2.0 * a * den
    s = stress
    r = np.empty((n, 4))
    r[:, 0] = cs * cs * s[:, 0] + 2 * cs * sn * s[:, 3] + sn * sn * s[:, 1]
    r[:, 1] = sn * sn * s[:, 0] - 2 * cs * sn * s[:, 3] + cs * cs * s[:, 1]
    r[:, 2] = s[:, 2]
    r[:, 3] = -cs * sn * s[:, 0] + (cs * cs - sn * sn) * s[:, 3] + cs * sn * s[:, 1]
    sy = prm[P_SY0] + prm[P_H] * eps_p
    hr = prm[P_H]
    new, dep = _j2(r, d, dt, G, lam, sy, hr)
    if mode == MODE_PLANE_STRESS:
        tol = 1e-12 * (sy + np.abs(new[:, 0]) + np.abs(new[:, 1]))
        idx = np.flatnonzero((dep > 0) & (np.abs(new[:, 2]) > tol))
        if idx.size:
            z0 = d[idx, 2].copy()
            r0 = new[idx, 2].copy()
            z1 = z0 - r0 / ((lam + 2 * G) * dt)
            dd = d[idx].copy()
            for _ in range(30):
                dd[:, 2] = z1
                nn, dp = _j2(r[idx], dd, dt, G, lam, sy[idx], hr)
                rz = nn[:, 2]
                done = (np.abs(rz) <= tol[idx]) | (rz == r0)
                new[idx], dep[idx] = nn, dp
                if done.all():
                    break
                with np.errstate(divide="ignore", invalid="ignore"):
                    z2 = np.where(done, z1, z1 - rz * (z1 - z0) / (rz - r0))
                z0, r0, z1 = z1, rz, z2
            d[idx, 2] = z1
        new[:, 2] = 0.0
    stress[:] = new
    eps_p += dep
    x0, x1, x2 = X[0]
    y0, y1, y2 = X[1]
    l2 = np.maximum(np.maximum((x1 - x0) ** 2 + (y1 - y0) ** 2, (x2 - x1) ** 2 + (y2 - y1) ** 2),
                    (x0 - x2) ** 2 + (y0 - y2) ** 2)
    le = tn / np.sqrt(l2)
    trd = d[:, 0] + d[:, 1] + d[:, 2]
    q = np.zeros(n)
    xi = np.zeros(n)
    if prm[P_BULK] > 0:
        b1, b2 = prm[P_B1], prm[P_B2]
        comp = np.minimum(trd, 0.0)
        q = b1 * rho * c * le * (-trd) + rho * (b2 * le * comp) ** 2
        xi = b1 + b2 * b2 * le / c * (-comp)
    dte = le / c * (np.sqrt(1 + xi * xi) - xi)
    if mode == MODE_AXISYMMETRIC:
        volm = 2 * np.pi * rm * 0.5 * ta
        rc = (x0 + x1 + x2) / 3.0
        vol = 2 * np.pi * rc * 0.5 * tn
    else:
        volm = prm[P_THICK] * 0.5 * ta
        vol = prm[P_THICK] * 0.5 * tn
    acc[0] += np.sum((sy + hr * dep) * dep * volm)
    tr_work = d[:, 0] + d[:, 1] if mode == MODE_PLANE_STRESS else trd
    acc[1] += np.sum(-q * tr_work * volm * dt)
    exx, eyy, ezz, exy = new[:, 0] - q, new[:, 1] - q, new[:, 2] - q, new[:, 3]
    sc = vol / tn
    fx = (exx * gnx + exy * gny) * sc                   # (3, n)
    fy = (exy * gnx + eyy * gny) * sc
    if mode == MODE_AXISYMMETRIC:
        fx += 2 * np.pi * 0.5 * tn * ezz / 3.0
    if bad.any():
        fx[:, bad] = 0.0
        fy[:, bad] = 0.0
    nn_ = f_int.shape[0]
    flat = ct.ravel()
    f_int[:, 0] += np.bincount(flat, weights=fx.ravel(), minlength=nn_)
    f_int[:, 1] += np.bincount(flat, weights=fy.ravel(), minlength=nn_)
    return float(np.min(np.where(bad, np.inf, dte))) if n else 1e300
