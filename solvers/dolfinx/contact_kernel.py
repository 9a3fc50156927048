"""Compiled node-to-segment soft-contact pass (eq. 5), the same algorithm and rounding as
:func:`.contact.soft_contact_pass`, on the arrays of :class:`ContactArrays`.

Candidates: the 8 nearest master-segment midpoints within the search radius (a bucket grid,
:mod:`.cell_list`, instead of a k-d tree); per slave node the valid candidate with the least
overshoot beyond the segment's ends, then the smallest |h|, then the lowest segment key wins.
"""
from __future__ import annotations

import math
from collections import namedtuple

import numba
import numpy as np

from .cell_list import grid_build, grid_nearest
from .reductions import np_sum

__all__ = ["ContactArrays", "surface_geometry", "contact_pass", "EV_PENETRATION"]

#: event code of a penetration (h <= 0, or a node behind its previous segment)
EV_PENETRATION = 3
_N_CANDIDATES = 8
_XI_TOL = 0.02

#: Arrays of every contact surface (concatenated) and pass; see ``block_data.build_contact``.
ContactArrays = namedtuple("ContactArrays", [
    "node_off", "rows", "mass", "seg_off", "seg", "key", "f0_off", "f0", "f1_off", "f1",
    "xs", "vs", "wa", "wb", "snrm", "fs", "fs_prev", "midx", "midy", "ln",
    "p_slave", "p_master", "p_weight", "p_k", "p_h0", "p_mu", "p_nu", "p_eps2",
    "prev_off", "prev", "pres", "gap",
    "c_si", "c_mj", "c_xi", "c_n0", "c_n1", "c_h", "c_term", "acc_a", "acc_b",
    "g_head", "g_next", "g_meta", "q_idx", "q_d2", "work"])


@numba.njit(cache=True)
def surface_geometry(C, X, V, axisym, thickness):
    """Gather every surface's node positions and velocities, and its segment areas and normals
    (:meth:`.body.Body.segment_weights`)."""
    for i in range(C.rows.shape[0]):
        r = C.rows[i]
        C.xs[i, 0] = X[r, 0]
        C.xs[i, 1] = X[r, 1]
        C.vs[i, 0] = V[r, 0]
        C.vs[i, 1] = V[r, 1]
    twopi = 2 * np.pi
    for s in range(C.node_off.shape[0] - 1):
        n0 = C.node_off[s]
        for j in range(C.seg_off[s], C.seg_off[s + 1]):
            a = n0 + C.seg[j, 0]
            b = n0 + C.seg[j, 1]
            t0 = C.xs[b, 0] - C.xs[a, 0]
            t1 = C.xs[b, 1] - C.xs[a, 1]
            ln = math.sqrt(t0 * t0 + t1 * t1)
            if axisym:
                C.wa[j] = twopi * ln * (2 * C.xs[a, 0] + C.xs[b, 0]) / 6.0
                C.wb[j] = twopi * ln * (C.xs[a, 0] + 2 * C.xs[b, 0]) / 6.0
            else:
                C.wa[j] = 0.5 * ln * thickness
                C.wb[j] = C.wa[j]
            C.snrm[j, 0] = t1 / ln
            C.snrm[j, 1] = -t0 / ln


@numba.njit(cache=True)
def _tunnel(C, p, sn0, mn0, ms0, ns, ev, evf):
    """Penetration by a node that was in contact and now lies behind its previous segment."""
    po = C.prev_off[p]
    best = -1
    hbest = 0.0
    for i in range(ns):
        j = C.prev[po + i]
        if j < 0:
            continue
        a = mn0 + C.seg[ms0 + j, 0]
        b = mn0 + C.seg[ms0 + j, 1]
        t0 = C.xs[b, 0] - C.xs[a, 0]
        t1 = C.xs[b, 1] - C.xs[a, 1]
        L2 = t0 * t0 + t1 * t1
        d0 = C.xs[sn0 + i, 0] - C.xs[a, 0]
        d1 = C.xs[sn0 + i, 1] - C.xs[a, 1]
        xi = (d0 * t0 + d1 * t1) / L2
        h = (d0 * t1 - d1 * t0) / math.sqrt(L2)
        if h <= 0.0 and xi >= -_XI_TOL and xi <= 1 + _XI_TOL:
            if best < 0 or h < hbest:
                best = i
                hbest = h
    if best >= 0:
        ev[0] = EV_PENETRATION
        ev[1] = p
        ev[2] = best
        evf[0] = hbest
        return True
    return False


@numba.njit(cache=True)
def contact_pass(C, p, dt, ev, evf):
    """Pass ``p``: forces of its slave surface nodes against its master segments, added to
    ``C.fs`` (slave and master nodes); ``C.pres`` / ``C.gap`` / ``C.prev`` of the pass are set.

    Returns the stored layer energy of the pass (J); on a penetration, sets ``ev`` = [code, pass,
    slave node] and ``evf[0]`` = h and returns 0 without changing forces.
    """
    ss = C.p_slave[p]
    ms = C.p_master[p]
    sn0 = C.node_off[ss]
    ns = C.node_off[ss + 1] - sn0
    mn0 = C.node_off[ms]
    nm = C.node_off[ms + 1] - mn0
    ms0 = C.seg_off[ms]
    nseg = C.seg_off[ms + 1] - ms0
    po = C.prev_off[p]
    if _tunnel(C, p, sn0, mn0, ms0, ns, ev, evf):
        return 0.0
    for i in range(ns):
        C.pres[po + i] = np.nan
        C.gap[po + i] = np.nan
        C.prev[po + i] = -1
    if ns == 0 or nseg == 0:
        return 0.0
    h0 = C.p_h0[p]
    lnmax = 0.0
    lox = 1e300
    loy = 1e300
    hix = -1e300
    hiy = -1e300
    for j in range(nseg):
        a = mn0 + C.seg[ms0 + j, 0]
        b = mn0 + C.seg[ms0 + j, 1]
        t0 = C.xs[b, 0] - C.xs[a, 0]
        t1 = C.xs[b, 1] - C.xs[a, 1]
        ln = math.sqrt(t0 * t0 + t1 * t1)
        C.ln[j] = ln
        lnmax = max(lnmax, ln)
        C.midx[j] = 0.5 * (C.xs[a, 0] + C.xs[b, 0])
        C.midy[j] = 0.5 * (C.xs[a, 1] + C.xs[b, 1])
        lox = min(lox, min(C.xs[a, 0], C.xs[b, 0]))
        loy = min(loy, min(C.xs[a, 1], C.xs[b, 1]))
        hix = max(hix, max(C.xs[a, 0], C.xs[b, 0]))
        hiy = max(hiy, max(C.xs[a, 1], C.xs[b, 1]))
    radius = 0.5 * lnmax * (1 + _XI_TOL) + h0
    lox -= radius
    loy -= radius
    hix += radius
    hiy += radius
    grid_build(C.midx, C.midy, nseg, radius, C.g_head, C.g_next, C.g_meta)
    q = 1e-9 * h0
    nc = 0
    for i in range(ns):
        x0 = C.xs[sn0 + i, 0]
        y0 = C.xs[sn0 + i, 1]
        if not (x0 >= lox and x0 <= hix and y0 >= loy and y0 <= hiy):
            continue
        m = grid_nearest(x0, y0, radius, C.midx, C.midy, C.g_head, C.g_next, C.g_meta,
                         _N_CANDIDATES, C.q_idx, C.q_d2)
        best = -1
        bo = 0.0
        bh = 0.0
        bk = 0
        bxi = 0.0
        bn0 = 0.0
        bn1 = 0.0
        bhh = 0.0
        for c in range(m):
            j = C.q_idx[c]
            a = mn0 + C.seg[ms0 + j, 0]
            b = mn0 + C.seg[ms0 + j, 1]
            t0 = C.xs[b, 0] - C.xs[a, 0]
            t1 = C.xs[b, 1] - C.xs[a, 1]
            L = C.ln[j]
            d0 = x0 - C.xs[a, 0]
            d1 = y0 - C.xs[a, 1]
            xi = (d0 * t0 + d1 * t1) / (L * L)
            n0 = t1 / L
            n1 = -t0 / L
            h = d0 * n0 + d1 * n1
            if not (xi >= -_XI_TOL and xi <= 1 + _XI_TOL and h < h0 and h > -h0):
                continue
            over = max(max(-xi, xi - 1.0), 0.0) * L
            oq = np.rint(over / q)
            hq = np.rint(abs(h) / q)
            k = C.key[ms0 + j]
            if best < 0 or oq < bo or (oq == bo and (hq < bh or (hq == bh and k < bk))):
                best = j
                bo = oq
                bh = hq
                bk = k
                bxi = xi
                bn0 = n0
                bn1 = n1
                bhh = h
        if best >= 0:
            C.c_si[nc] = i
            C.c_mj[nc] = best
            C.c_xi[nc] = bxi
            C.c_n0[nc] = bn0
            C.c_n1[nc] = bn1
            C.c_h[nc] = bhh
            nc += 1
    if nc == 0:
        return 0.0
    worst = -1
    for c in range(nc):
        if C.c_h[c] <= 0.0 and (worst < 0 or C.c_h[c] < C.c_h[worst]):
            worst = c
    if worst >= 0:
        ev[0] = EV_PENETRATION
        ev[1] = p
        ev[2] = C.c_si[worst]
        evf[0] = C.c_h[worst]
        return 0.0
    kk = C.p_k[p]
    nu = C.p_nu[p]
    mu = C.p_mu[p]
    eps2 = C.p_eps2[p]
    wgt = C.p_weight[p]
    for i in range(nm):
        C.acc_a[i, 0] = 0.0
        C.acc_a[i, 1] = 0.0
        C.acc_b[i, 0] = 0.0
        C.acc_b[i, 1] = 0.0
    for c in range(nc):
        i = C.c_si[c]
        j = C.c_mj[c]
        h = C.c_h[c]
        n0 = C.c_n0[c]
        n1 = C.c_n1[c]
        xc = min(max(C.c_xi[c], 0.0), 1.0)
        ia = C.seg[ms0 + j, 0]
        ib = C.seg[ms0 + j, 1]
        vm0 = (1 - xc) * C.vs[mn0 + ia, 0] + xc * C.vs[mn0 + ib, 0]
        vm1 = (1 - xc) * C.vs[mn0 + ia, 1] + xc * C.vs[mn0 + ib, 1]
        vr0 = C.vs[sn0 + i, 0] - vm0
        vr1 = C.vs[sn0 + i, 1] - vm1
        vn = vr0 * n0 + vr1 * n1
        p_el = kk * (1.0 / h - 1.0 / h0)
        p_v = -nu * abs(vn) * vn
        pp = p_el + p_v
        # contact area: the node's adjacent slave segments projected on the contact plane
        g = sn0 + i
        A0 = 0.0
        for e in range(C.f0_off[g], C.f0_off[g + 1]):
            s = C.f0[e]
            A0 += max(0.0, -(C.snrm[s, 0] * n0 + C.snrm[s, 1] * n1)) * C.wa[s]
        A1 = 0.0
        for e in range(C.f1_off[g], C.f1_off[g + 1]):
            s = C.f1[e]
            A1 += max(0.0, -(C.snrm[s, 0] * n0 + C.snrm[s, 1] * n1)) * C.wb[s]
        A = A0 + A1
        fa = wgt * pp * A
        F0 = fa * n0
        F1 = fa * n1
        if mu > 0:
            vt0 = vr0 - vn * n0
            vt1 = vr1 - vn * n1
            vtn = math.sqrt((vt0 * vt0 + vt1 * vt1) + eps2)
            mag = wgt * mu * max(pp, 0.0) * A / vtn
            if dt > 0:
                mm = (1 - xc) * C.mass[mn0 + ia] + xc * C.mass[mn0 + ib]
                msl = C.mass[sn0 + i]
                meff = msl * mm / (msl + mm)
                mag = min(mag, 0.5 * meff / dt)
            F0 += -mag * vt0
            F1 += -mag * vt1
        C.fs[sn0 + i, 0] += F0
        C.fs[sn0 + i, 1] += F1
        C.acc_a[ia, 0] += (1 - xc) * F0
        C.acc_a[ia, 1] += (1 - xc) * F1
        C.acc_b[ib, 0] += xc * F0
        C.acc_b[ib, 1] += xc * F1
        C.pres[po + i] = pp
        C.gap[po + i] = h
        C.prev[po + i] = j
        C.c_term[c] = wgt * A * kk * (math.log(h0 / h) - (h0 - h) / h0)
    for i in range(nm):
        C.fs[mn0 + i, 0] += -(C.acc_a[i, 0] + C.acc_b[i, 0])
        C.fs[mn0 + i, 1] += -(C.acc_a[i, 1] + C.acc_b[i, 1])
    return np_sum(C.c_term, nc)
