"""Vectorised form of the 3D element kernel (:func:`.tet_kernel.tet_step`), the 2D kernel's
structure (:mod:`.kernels`): batches of ``BATCH`` tetrahedra are gathered into a
structure-of-arrays scratch, updated by a loop without data-dependent control flow (selects, so
that LLVM vectorises it over cells) and scattered back in cell order.

The formulas are those of :func:`.tet_kernel.tet_step`, written out again in the same order, so
that every cell gets the same bits (``tests/mechanics/test_3d_kernel.py`` compares the two with
``np.array_equal``). Rate-independent materials with the linear law; the solver uses the scalar kernel
for a material with the linear law and a rate law. A general material (another flow curve, or a temperature
per cell: :func:`.element_math.general_material`) is screened in the batches: a cell whose trial stress
stays below the lower bound of its yield stress (:func:`.flow_curves.flow_floor`, scratch row 31) is
elastic and done there; every other cell is updated by the scalar kernel on its own (:func:`_redo_cell`),
its results written into the batch's rows, so that the forces are added in cell order as in the scalar
kernel: the same bits as :func:`.tet_kernel.tet_step`.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from .element_math import (BATCH, FM, P_B1, P_B2, P_BULK, P_G, P_H, P_K, P_RATE, P_RHO, P_SY0,
                           ROW, add_chunk_part, general_material)
from .flow_curves import flow_floor
from .kernel_layout import P_T0
from .tet_kernel import (_NO_SHARED, add_tet_forces, clear_tet_forces, store_tet_forces,
                         tet_cell, tet_chunk_scalar, tet_chunk_size)

__all__ = ["tet_step_batched", "tet_chunk_batched", "tet_chunk", "batched_material", "TET_WORK_SIZE"]

#: scratch rows in: positions of the 4 nodes (0-11: x0 y0 z0 x1 ...), velocities (12-23),
#: stress (24-29), plastic strain (30), a general material's lower bound of the yield stress (31)
_IN = 32
#: scratch rows out: stress (0-5), plastic strain (6), forces of nodes 1-3 (7-15), critical step
#: (16), plastic and bulk-viscous dissipation (17, 18), status (19: 1 done, 0 inverted, 2 to be
#: redone by the scalar kernel)
_OUT = 20
#: a redone cell's scratch (:func:`.tet_kernel.tet_cell`'s results)
_ONE = 16
#: float64 length of the scratch of :func:`tet_step_batched` (the batches', a redone cell's, then 4
#: for a chunk's results)
TET_WORK_SIZE = (_IN + _OUT) * ROW + _ONE + 4


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def _batch(inp, out, n, dt, prm):
    """Update ``n`` <= BATCH cells of the scratch (see the row layout above)."""
    rho = prm[P_RHO]
    G = prm[P_G]
    K = prm[P_K]
    lam = K - 2.0 * G / 3.0
    sy0 = prm[P_SY0]
    H = prm[P_H]
    screen = general_material(prm)
    b1 = prm[P_B1]
    b2 = prm[P_B2]
    bulk = prm[P_BULK] > 0.0
    c = math.sqrt((K + 4.0 * G / 3.0) / rho)
    hdt = 0.5 * dt
    for j in range(n):
        x0 = inp[0 * ROW + j]
        y0 = inp[1 * ROW + j]
        z0 = inp[2 * ROW + j]
        vx0 = inp[12 * ROW + j]
        vy0 = inp[13 * ROW + j]
        vz0 = inp[14 * ROW + j]
        u1x = inp[15 * ROW + j] - vx0
        u1y = inp[16 * ROW + j] - vy0
        u1z = inp[17 * ROW + j] - vz0
        u2x = inp[18 * ROW + j] - vx0
        u2y = inp[19 * ROW + j] - vy0
        u2z = inp[20 * ROW + j] - vz0
        u3x = inp[21 * ROW + j] - vx0
        u3y = inp[22 * ROW + j] - vy0
        u3z = inp[23 * ROW + j] - vz0
        ax = inp[3 * ROW + j] - x0
        ay = inp[4 * ROW + j] - y0
        az = inp[5 * ROW + j] - z0
        bx = inp[6 * ROW + j] - x0
        by = inp[7 * ROW + j] - y0
        bz = inp[8 * ROW + j] - z0
        cx = inp[9 * ROW + j] - x0
        cy = inp[10 * ROW + j] - y0
        cz = inp[11 * ROW + j] - z0
        max_ = ax - hdt * u1x
        may = ay - hdt * u1y
        maz = az - hdt * u1z
        mbx = bx - hdt * u2x
        mby = by - hdt * u2y
        mbz = bz - hdt * u2z
        mcx = cx - hdt * u3x
        mcy = cy - hdt * u3y
        mcz = cz - hdt * u3z
        g1x = mby * mcz - mbz * mcy
        g1y = mbz * mcx - mbx * mcz
        g1z = mbx * mcy - mby * mcx
        g2x = mcy * maz - mcz * may
        g2y = mcz * max_ - mcx * maz
        g2z = mcx * may - mcy * max_
        g3x = may * mbz - maz * mby
        g3y = maz * mbx - max_ * mbz
        g3z = max_ * mby - may * mbx
        detm = max_ * g1x + may * g1y + maz * g1z
        n1x = by * cz - bz * cy
        n1y = bz * cx - bx * cz
        n1z = bx * cy - by * cx
        n2x = cy * az - cz * ay
        n2y = cz * ax - cx * az
        n2z = cx * ay - cy * ax
        n3x = ay * bz - az * by
        n3y = az * bx - ax * bz
        n3z = ax * by - ay * bx
        detn = ax * n1x + ay * n1y + az * n1z
        ok = (detm > 0.0) & (detn > 0.0)
        inv = 1.0 / detm
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
        sxx = inp[24 * ROW + j]
        syy = inp[25 * ROW + j]
        szz = inp[26 * ROW + j]
        sxy = inp[27 * ROW + j]
        syz = inp[28 * ROW + j]
        sxz = inp[29 * ROW + j]
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
        ep = inp[30 * ROW + j]
        sy = inp[31 * ROW + j] if screen else (sy0 + H * ep) * 1.0
        hr = H * 1.0
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
        plastic = qm > sy
        dep = (qm - sy) / (3.0 * G + hr) if plastic else 0.0
        f = 1.0 - 3.0 * G * dep / qm if plastic else 1.0
        txx = exx * f + p if plastic else txx
        tyy = eyy * f + p if plastic else tyy
        tzz = ezz * f + p if plastic else tzz
        txy = txy * f if plastic else txy
        tyz = tyz * f if plastic else tyz
        txz = txz * f if plastic else txz
        out[0 * ROW + j] = txx
        out[1 * ROW + j] = tyy
        out[2 * ROW + j] = tzz
        out[3 * ROW + j] = txy
        out[4 * ROW + j] = tyz
        out[5 * ROW + j] = txz
        out[6 * ROW + j] = ep + dep
        n0x = n1x + n2x + n3x
        n0y = n1y + n2y + n3y
        n0z = n1z + n2z + n3z
        amax = max(max(n0x * n0x + n0y * n0y + n0z * n0z, n1x * n1x + n1y * n1y + n1z * n1z),
                   max(n2x * n2x + n2y * n2y + n2z * n2z, n3x * n3x + n3y * n3y + n3z * n3z))
        le = detn / math.sqrt(amax)
        comp = bulk & (trd < 0.0)
        q1 = b1 * rho * c * le * (-trd) if bulk else 0.0
        q = q1 + rho * (b2 * le * trd) ** 2 if comp else q1
        xi1 = b1 if bulk else 0.0
        xi = xi1 + b2 * b2 * le / c * (-trd) if comp else xi1
        out[16 * ROW + j] = le / c * (math.sqrt(1.0 + xi * xi) - xi)
        volm = detm / 6.0
        out[17 * ROW + j] = (sy + hr * dep) * dep * volm
        out[18 * ROW + j] = -q * trd * volm * dt
        sx = (txx - q) / 6.0
        sy_ = (tyy - q) / 6.0
        sz = (tzz - q) / 6.0
        sxy6 = txy / 6.0
        syz6 = tyz / 6.0
        sxz6 = txz / 6.0
        out[7 * ROW + j] = sx * n1x + sxy6 * n1y + sxz6 * n1z
        out[8 * ROW + j] = sxy6 * n1x + sy_ * n1y + syz6 * n1z
        out[9 * ROW + j] = sxz6 * n1x + syz6 * n1y + sz * n1z
        out[10 * ROW + j] = sx * n2x + sxy6 * n2y + sxz6 * n2z
        out[11 * ROW + j] = sxy6 * n2x + sy_ * n2y + syz6 * n2z
        out[12 * ROW + j] = sxz6 * n2x + syz6 * n2y + sz * n2z
        out[13 * ROW + j] = sx * n3x + sxy6 * n3y + sxz6 * n3z
        out[14 * ROW + j] = sxy6 * n3x + sy_ * n3y + syz6 * n3z
        out[15 * ROW + j] = sxz6 * n3x + syz6 * n3y + sz * n3z
        status = 1.0 if ok else 0.0
        out[19 * ROW + j] = 2.0 if ok & screen & plastic else status


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def tet_step_batched(cells, x, v, dt, prm, stress, eps_p, f_int, acc, work, temp):
    """:func:`.tet_kernel.tet_step` in vectorised batches (same arguments, same results to the
    bit; rate-independent materials, or a general material screened: see the module docstring), in
    the same chunks (:func:`tet_chunk_batched`). ``work``: float64 scratch of :data:`TET_WORK_SIZE`
    (a shorter one: allocated per call); ``temp``: the temperature per cell (K), or empty."""
    scratch = work if work.shape[0] >= TET_WORK_SIZE else np.empty(TET_WORK_SIZE)
    part = scratch[TET_WORK_SIZE - 4:TET_WORK_SIZE]
    no_fe = scratch[:0].reshape(0, 12)
    nc = cells.shape[0]
    dtmin = 1e300
    wp = 0.0
    wv = 0.0
    acc[2] = -1.0
    cs = tet_chunk_size(nc)
    for e0 in range(0, nc, cs):
        tet_chunk_batched(cells, x, v, dt, prm, stress, eps_p, f_int, no_fe, _NO_SHARED, e0,
                          min(nc, e0 + cs), scratch, part, temp)
        dtmin, wp, wv, acc[2] = add_chunk_part(part, dtmin, wp, wv, acc[2])
    acc[0] += wp
    acc[1] += wv
    return dtmin


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def tet_chunk_batched(cells, x, v, dt, prm, stress, eps_p, f_int, fe, shared, e0, e1, work, part, temp):
    """Cells ``e0:e1`` of :func:`tet_step_batched`: the arguments of
    :func:`.tet_kernel.tet_chunk_scalar` and ``work`` (its scratch, at least
    ``TET_WORK_SIZE - 4`` float64); the same results to the bit (rate-independent materials, or a
    general material, screened)."""
    inp = work[:_IN * ROW]
    out = work[_IN * ROW:(_IN + _OUT) * ROW]
    one = work[(_IN + _OUT) * ROW:(_IN + _OUT) * ROW + _ONE]
    screen = general_material(prm)
    has_t = temp.shape[0] > 0
    store = fe.shape[0] > 0
    dtmin = 1e300
    wp = 0.0
    wv = 0.0
    bad = -1.0
    for s in range(e0, e1, BATCH):
        n = min(BATCH, e1 - s)
        for j in range(n):
            e = s + j
            for k in range(4):
                i = cells[e, k]
                inp[(3 * k) * ROW + j] = x[i, 0]
                inp[(3 * k + 1) * ROW + j] = x[i, 1]
                inp[(3 * k + 2) * ROW + j] = x[i, 2]
                inp[(12 + 3 * k) * ROW + j] = v[i, 0]
                inp[(13 + 3 * k) * ROW + j] = v[i, 1]
                inp[(14 + 3 * k) * ROW + j] = v[i, 2]
            for r in range(6):
                inp[(24 + r) * ROW + j] = stress[e, r]
            inp[30 * ROW + j] = eps_p[e]
            if screen:
                inp[31 * ROW + j] = flow_floor(prm, eps_p[e], temp[e] if has_t else prm[P_T0])
        _batch(inp, out, n, dt, prm)
        if screen:
            for j in range(n):
                if out[19 * ROW + j] == 2.0:
                    _redo_cell(cells, x, v, dt, prm, stress, eps_p, temp, s + j, one, out, j)
        for j in range(n):
            e = s + j
            if out[19 * ROW + j] == 0.0:
                if bad < 0.0:
                    bad = e
                continue
            for r in range(6):
                stress[e, r] = out[r * ROW + j]
            eps_p[e] = out[6 * ROW + j]
            dte = out[16 * ROW + j]
            if dte < dtmin:
                dtmin = dte
            wp += out[17 * ROW + j]
            wv += out[18 * ROW + j]
        # the forces in a loop of their own per case (one loop with both cases ran 1.5x slower)
        if store:
            _store_batch(cells, out, s, n, f_int, fe, shared)
        else:
            for j in range(n):
                if out[19 * ROW + j] != 0.0:
                    e = s + j
                    add_tet_forces(f_int, cells[e, 0], cells[e, 1], cells[e, 2], cells[e, 3],
                                   out[7 * ROW + j], out[8 * ROW + j], out[9 * ROW + j],
                                   out[10 * ROW + j], out[11 * ROW + j], out[12 * ROW + j],
                                   out[13 * ROW + j], out[14 * ROW + j], out[15 * ROW + j])
    part[0] = dtmin
    part[1] = wp
    part[2] = wv
    part[3] = bad


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def _redo_cell(cells, x, v, dt, prm, stress, eps_p, temp, e, res, out, j):
    """Cell ``e`` by the scalar kernel's :func:`.tet_kernel.tet_cell` (its stress, plastic strain and
    temperature updated in place; ``res`` its scratch), its outputs written into column ``j`` of the
    batch's rows ``out`` (forces of nodes 1-3, critical step, dissipation, status), so that the batch
    adds its forces in cell order."""
    tet_cell(cells, x, v, dt, prm, stress, eps_p, temp, e, res)
    for r in range(6):
        out[r * ROW + j] = stress[e, r]
    out[6 * ROW + j] = eps_p[e]
    for r in range(9):
        out[(7 + r) * ROW + j] = res[r]
    out[16 * ROW + j] = res[9]
    out[17 * ROW + j] = res[10]
    out[18 * ROW + j] = res[11]
    out[19 * ROW + j] = res[12]


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def _store_batch(cells, out, s, n, f_int, fe, shared):
    """The forces of the batch's cells ``s:s+n`` for the threaded kernel
    (:func:`.tet_kernel.store_tet_forces`; an inverted cell stores none)."""
    for j in range(n):
        e = s + j
        if out[19 * ROW + j] == 0.0:
            clear_tet_forces(fe, shared, e, cells[e, 0], cells[e, 1], cells[e, 2], cells[e, 3])
            continue
        store_tet_forces(f_int, fe, shared, e, cells[e, 0], cells[e, 1], cells[e, 2], cells[e, 3],
                         out[7 * ROW + j], out[8 * ROW + j], out[9 * ROW + j],
                         out[10 * ROW + j], out[11 * ROW + j], out[12 * ROW + j],
                         out[13 * ROW + j], out[14 * ROW + j], out[15 * ROW + j])


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def tet_chunk(cells, x, v, dt, prm, stress, eps_p, f_int, fe, shared, e0, e1, work, part, temp):
    """Cells ``e0:e1`` by the solver's kernel for the material: :func:`tet_chunk_batched`
    (rate-independent, or a general material: a flow curve, a temperature per cell in ``temp``), else
    :func:`.tet_kernel.tet_chunk_scalar` (the linear law with a rate law); same arguments."""
    if batched_material(prm):
        tet_chunk_batched(cells, x, v, dt, prm, stress, eps_p, f_int, fe, shared, e0, e1, work,
                          part, temp)
    else:
        tet_chunk_scalar(cells, x, v, dt, prm, stress, eps_p, f_int, fe, shared, e0, e1, part, temp)


@numba.njit(cache=True)
def batched_material(prm):
    """Whether the vectorised 3D kernel serves the material: no rate law, or a general material
    (:func:`.element_math.general_material`; screened, its yielding cells by the scalar kernel)."""
    return prm[P_RATE] == 0 or general_material(prm)
