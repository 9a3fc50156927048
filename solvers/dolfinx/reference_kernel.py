"""Plain vectorised-numpy version of :func:`.kernels.element_step` (gather + einsum + bincount).

Same algorithm as the compiled kernel; it exists as a cross-check and as the benchmark baseline.
Only rate-independent materials are supported here.
"""
from __future__ import annotations

import numpy as np

from .kernels import (MODE_AXISYMMETRIC, MODE_PLANE_STRAIN, MODE_PLANE_STRESS, P_B1, P_B2, P_BULK,
                      P_G, P_H, P_K, P_MODE, P_RATE, P_RHO, P_SY0, P_THICK)

__all__ = ["element_step_numpy"]


def _j2(s, d, dt, G, lam, sy, hr):
    """Vectorised predictor + radial return; s, d: (n, 4) [xx, yy, zz, xy]."""
    tr = d[:, :3].sum(axis=1) * dt
    t = s + 2.0 * G * dt * d
    t[:, :3] += (lam * tr)[:, None]
    p = t[:, :3].mean(axis=1)
    dev = t.copy()
    dev[:, :3] -= p[:, None]
    q = np.sqrt(1.5 * (np.einsum("ij,ij->i", dev[:, :3], dev[:, :3]) + 2.0 * dev[:, 3] ** 2))
    dep = np.where(q > sy, (q - sy) / (3.0 * G + hr), 0.0)
    fac = np.where(q > sy, 1.0 - 3.0 * G * dep / np.where(q > 0, q, 1.0), 1.0)
    out = dev * fac[:, None]
    out[:, :3] += p[:, None]
    return out, dep


def element_step_numpy(cells, x, v, dt, prm, stress, eps_p, f_int, acc):
    """Vectorised-numpy twin of :func:`.kernels.element_step` (same arguments and return value)."""
    if int(prm[P_RATE]) != 0:
        raise NotImplementedError("the numpy reference kernel supports rate-independent materials")
    rho, G, K = prm[P_RHO], prm[P_G], prm[P_K]
    lam = K - 2.0 * G / 3.0
    mode = int(prm[P_MODE])
    c = np.sqrt((K + 4.0 * G / 3.0) / rho)
    n = cells.shape[0]
    xe = x[cells]                      # (n, 3, 2) gather
    ve = v[cells]
    xm = xe - 0.5 * dt * ve
    acc[2] = -1.0

    def grads(xc):
        ta = ((xc[:, 1, 0] - xc[:, 0, 0]) * (xc[:, 2, 1] - xc[:, 0, 1])
              - (xc[:, 2, 0] - xc[:, 0, 0]) * (xc[:, 1, 1] - xc[:, 0, 1]))
        g = np.empty((xc.shape[0], 3, 2))
        g[:, 0, 0] = xc[:, 1, 1] - xc[:, 2, 1]
        g[:, 1, 0] = xc[:, 2, 1] - xc[:, 0, 1]
        g[:, 2, 0] = xc[:, 0, 1] - xc[:, 1, 1]
        g[:, 0, 1] = xc[:, 2, 0] - xc[:, 1, 0]
        g[:, 1, 1] = xc[:, 0, 0] - xc[:, 2, 0]
        g[:, 2, 1] = xc[:, 1, 0] - xc[:, 0, 0]
        return ta, g

    ta, gm = grads(xm)
    tn, gn = grads(xe)
    bad = (ta <= 0) | (tn <= 0)
    if bad.any():
        acc[2] = float(np.flatnonzero(bad)[0])
    ta = np.where(bad, 1.0, ta)
    tn = np.where(bad, 1.0, tn)
    L = np.einsum("nai,naj->nij", ve, gm) / ta[:, None, None]    # L[i, j] = d v_i / d x_j
    d = np.empty((n, 4))
    d[:, 0] = L[:, 0, 0]
    d[:, 1] = L[:, 1, 1]
    d[:, 3] = 0.5 * (L[:, 0, 1] + L[:, 1, 0])
    w = 0.5 * (L[:, 0, 1] - L[:, 1, 0])
    if mode == MODE_AXISYMMETRIC:
        d[:, 2] = ve[:, :, 0].sum(axis=1) / xm[:, :, 0].sum(axis=1)
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
    le = tn / np.sqrt(np.max(np.stack([((xe[:, 1] - xe[:, 0]) ** 2).sum(1),
                                         ((xe[:, 2] - xe[:, 1]) ** 2).sum(1),
                                         ((xe[:, 0] - xe[:, 2]) ** 2).sum(1)]), axis=0))
    trd = d[:, :3].sum(axis=1)
    q = np.zeros(n)
    xi = np.zeros(n)
    if prm[P_BULK] > 0:
        b1, b2 = prm[P_B1], prm[P_B2]
        comp = np.minimum(trd, 0.0)
        q = b1 * rho * c * le * (-trd) + rho * (b2 * le * comp) ** 2
        xi = b1 + b2 * b2 * le / c * (-comp)
    dte = le / c * (np.sqrt(1 + xi * xi) - xi)
    if mode == MODE_AXISYMMETRIC:
        volm = 2 * np.pi * xm[:, :, 0].mean(axis=1) * 0.5 * ta
        vol = 2 * np.pi * xe[:, :, 0].mean(axis=1) * 0.5 * tn
    else:
        volm = prm[P_THICK] * 0.5 * ta
        vol = prm[P_THICK] * 0.5 * tn
    acc[0] += np.sum((sy + hr * dep) * dep * volm)
    tr_work = d[:, 0] + d[:, 1] if mode == MODE_PLANE_STRESS else trd
    acc[1] += np.sum(-q * tr_work * volm * dt)
    e = new.copy()
    e[:, :3] -= q[:, None]
    sig = np.empty((n, 2, 2))
    sig[:, 0, 0], sig[:, 1, 1] = e[:, 0], e[:, 1]
    sig[:, 0, 1] = sig[:, 1, 0] = e[:, 3]
    fe = np.einsum("nij,naj->nai", sig, gn) * (vol / tn)[:, None, None]
    if mode == MODE_AXISYMMETRIC:
        fe[:, :, 0] += (2 * np.pi * 0.5 * tn * e[:, 2] / 3.0)[:, None]
    if bad.any():
        fe[bad] = 0.0
    nn_ = f_int.shape[0]
    flat = cells.ravel()
    f_int[:, 0] += np.bincount(flat, weights=fe[:, :, 0].ravel(), minlength=nn_)
    f_int[:, 1] += np.bincount(flat, weights=fe[:, :, 1].ravel(), minlength=nn_)
    return float(np.min(np.where(bad, np.inf, dte))) if n else 1e300
