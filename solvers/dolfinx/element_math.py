"""The mathematics of one explicit element update (objective stress update, J2 radial return, bulk
viscosity, internal nodal forces, critical time step) in two compiled forms with the same formulas:

* :func:`cell_update`: one cell, scalar; any rate law, and the plane-stress secant iteration (the point's
  stress update :func:`.point_math.point_update`, shared with the six-node kernel :mod:`.tri6_kernel`);
* :func:`batch_update`: a batch of cells held as rows of contiguous scratch arrays
  (structure of arrays), rate-independent only, written without data-dependent control flow so
  that LLVM vectorises it (SIMD over cells; the element kernel gathers into and scatters out of the
  scratch, see :func:`.kernels.element_step`). A plane-stress cell whose return needs the secant
  iteration on d_zz is flagged for :func:`cell_update`.

Conventions (see :mod:`.kernels`): triangles, Voigt stress ``[xx, yy, zz, xy]``, half-step
velocities, end-of-step positions, mid-step configuration for the velocity gradient, the
Hughes-Winget rotation, internal force with sigma^{n+1} on x^{n+1}.
"""
from __future__ import annotations

import math

import numba

__all__ = ["cell_update", "point_update", "batch_update", "rate_factor_at", "BATCH", "ROW", "IN_ROWS", "OUT_ROWS",
           "MODE_PLANE_STRESS", "MODE_PLANE_STRAIN", "MODE_AXISYMMETRIC", "FM", "N_PRM"]

from .kernel_layout import (FM, N_PRM, P_B1, P_B2, P_BETA, P_BULK, P_FLOW, P_G, P_H, P_K, P_MODE,  # noqa: F401
                            P_R1, P_R2, P_RATE, P_RHO, P_RHOCP, P_SY0, P_T0, P_THERM, P_THICK)
# the point's stress update (one home, shared with the six-node kernel); re-exported for the 3D kernels
from .point_math import (MODE_AXISYMMETRIC, MODE_PLANE_STRAIN, MODE_PLANE_STRESS, elastic_trial,  # noqa: F401
                         equivalent_rate, general_material, heated, j2_return, j2_return_flow, point_update,
                         rate_factor, rate_factor_at)


#: cells per batch, and the row length of the scratch arrays: padded so that the rows are not a
#: power-of-two number of bytes apart (rows 2 KiB apart alias in the L1 cache: 2x slower gather)
BATCH = 128
ROW = BATCH + 8
#: scratch rows in: node coordinates x0 y0 x1 y1 x2 y2 (0-5), velocities (6-11), stress (12-15),
#: plastic strain (16); a general material's (:func:`general_material`) lower bound of the yield
#: stress (17, :func:`.flow_curves.flow_floor`) and temperature (18)
IN_ROWS = 19
#: scratch rows out: stress (0-3), plastic strain (4), nodal forces f0x f0y f1x f1y f2x f2y (5-10),
#: hoop force per node (11), critical step (12), plastic and bulk-viscous dissipation (13, 14),
#: status (15: 1 done, 0 inverted, 2 to be redone by cell_update), temperature (16, cell_update)
OUT_ROWS = 17
ST_INVERTED = 0.0
ST_DONE = 1.0
ST_REDO = 2.0


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def cell_update(x0, y0, x1, y1, x2, y2, vx0, vy0, vx1, vy1, vx2, vy2, sxx, syy, szz, sxy, ep,
                dt, prm, out, T=-1.0):
    """One cell's update, scalar (any rate law and flow curve; the plane-stress secant iteration).

    Parameters
    ----------
    x0 ... y2 : float
        End-of-step node positions, m.
    vx0 ... vy2 : float
        Half-step node velocities, m/s.
    sxx, syy, szz, sxy : float
        Cauchy stress at the start of the step, Pa.
    ep : float
        Equivalent plastic strain at the start of the step.
    dt : float
        Step, s.
    prm : float64 array
        Kernel parameters (:func:`.kernels.pack_parameters`).
    out : float64 array (OUT_ROWS,)
        Receives the cell's outputs in the order of the scratch rows out (see ``OUT_ROWS``).
    T : float
        Temperature at the start of the step, K (negative: the material's initial temperature).
    """
    rho = prm[P_RHO]
    G = prm[P_G]
    K = prm[P_K]
    lam = K - 2.0 * G / 3.0
    b1 = prm[P_B1]
    b2 = prm[P_B2]
    bulk = prm[P_BULK]
    thick = prm[P_THICK]
    mode = int(prm[P_MODE])
    c = math.sqrt((K + 4.0 * G / 3.0) / rho)
    twopi = 2.0 * math.pi
    hdt = 0.5 * dt
    mx0 = x0 - hdt * vx0
    my0 = y0 - hdt * vy0
    mx1 = x1 - hdt * vx1
    my1 = y1 - hdt * vy1
    mx2 = x2 - hdt * vx2
    my2 = y2 - hdt * vy2
    ta = (mx1 - mx0) * (my2 - my0) - (mx2 - mx0) * (my1 - my0)
    tn = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    if ta <= 0.0 or tn <= 0.0:
        out[15] = ST_INVERTED
        return
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
    if T < 0.0:
        T = prm[P_T0]
    nxx, nyy, nzz, nxy, dep, sy, hr, dzz = point_update(sxx, syy, szz, sxy, ep, T, dxx, dyy, dzz, dxy, w, dt,
                                                        prm)
    out[0] = nxx
    out[1] = nyy
    out[2] = nzz
    out[3] = nxy
    out[4] = ep + dep
    out[16] = heated(T, sy, dep, prm)
    # geometry at the end of the step
    l01 = (x1 - x0) * (x1 - x0) + (y1 - y0) * (y1 - y0)
    l12 = (x2 - x1) * (x2 - x1) + (y2 - y1) * (y2 - y1)
    l20 = (x0 - x2) * (x0 - x2) + (y0 - y2) * (y0 - y2)
    le = tn / math.sqrt(max(l01, max(l12, l20)))
    trd = dxx + dyy + dzz
    q = 0.0
    xi = 0.0
    if bulk > 0.0:
        q = b1 * rho * c * le * (-trd)
        xi = b1
        if trd < 0.0:
            q += rho * (b2 * le * trd) ** 2
            xi += b2 * b2 * le / c * (-trd)
    out[12] = le / c * (math.sqrt(1.0 + xi * xi) - xi)
    # volumes (mid for dissipation, end for forces)
    if mode == MODE_AXISYMMETRIC:
        volm = twopi * (mx0 + mx1 + mx2) / 3.0 * 0.5 * ta
        vol = twopi * (x0 + x1 + x2) / 3.0 * 0.5 * tn
    else:
        volm = thick * 0.5 * ta
        vol = thick * 0.5 * tn
    out[13] = (sy + hr * dep) * dep * volm
    if mode == MODE_PLANE_STRESS:
        out[14] = -q * (dxx + dyy) * volm * dt
    else:
        out[14] = -q * trd * volm * dt
    exx = nxx - q
    eyy = nyy - q
    inv = vol / tn
    # d N / dx * vol, d N / dy * vol on the end configuration
    gx0 = (y1 - y2) * inv
    gx1 = (y2 - y0) * inv
    gx2 = (y0 - y1) * inv
    gy0 = (x2 - x1) * inv
    gy1 = (x0 - x2) * inv
    gy2 = (x1 - x0) * inv
    out[5] = exx * gx0 + nxy * gy0
    out[6] = nxy * gx0 + eyy * gy0
    out[7] = exx * gx1 + nxy * gy1
    out[8] = nxy * gx1 + eyy * gy1
    out[9] = exx * gx2 + nxy * gy2
    out[10] = nxy * gx2 + eyy * gy2
    out[11] = twopi * 0.5 * tn * (nzz - q) / 3.0 if mode == MODE_AXISYMMETRIC else 0.0
    out[15] = ST_DONE


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def batch_update(inp, out, n, dt, prm):
    """Update ``n`` <= BATCH cells held in the scratch ``inp`` (IN_ROWS x ROW, flattened) into
    ``out`` (OUT_ROWS x ROW, flattened); rate-independent materials with the linear law
    (``prm[P_RATE] == 0``), or, for a general material (:func:`general_material`), the elastic
    cells: a cell whose trial stress exceeds the lower bound of its yield stress (scratch row 17)
    is flagged for :func:`cell_update`.
    The formulas of :func:`cell_update`, with selects instead of branches so that the loop
    vectorises (LLVM also turns the branches on the formulation into selects: measured as fast as
    one loop per formulation, which took minutes to compile). They are written out again here on
    purpose: the loop vectorises only if everything in it is inlined, and sharing the formulas
    through ``inline="always"`` helpers made numba compile this function in 31 s instead of 1.4 s
    (same speed); ``test_batched_kernel_equals_the_scalar_cell_update`` keeps the two equal.

    Row ``15`` of ``out`` gives each cell's status: 1 done, 0 inverted (the rest of its outputs
    are meaningless), 2 a plane-stress return that needs the secant iteration (redo it with
    :func:`cell_update`).
    """
    mode = int(prm[P_MODE])
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
    thick = prm[P_THICK]
    c = math.sqrt((K + 4.0 * G / 3.0) / rho)
    twopi = 2.0 * math.pi
    hdt = 0.5 * dt
    for j in range(n):
        x0 = inp[0 * ROW + j]
        y0 = inp[1 * ROW + j]
        x1 = inp[2 * ROW + j]
        y1 = inp[3 * ROW + j]
        x2 = inp[4 * ROW + j]
        y2 = inp[5 * ROW + j]
        vx0 = inp[6 * ROW + j]
        vy0 = inp[7 * ROW + j]
        vx1 = inp[8 * ROW + j]
        vy1 = inp[9 * ROW + j]
        vx2 = inp[10 * ROW + j]
        vy2 = inp[11 * ROW + j]
        sxx = inp[12 * ROW + j]
        syy = inp[13 * ROW + j]
        szz = inp[14 * ROW + j]
        sxy = inp[15 * ROW + j]
        ep = inp[16 * ROW + j]
        mx0 = x0 - hdt * vx0
        my0 = y0 - hdt * vy0
        mx1 = x1 - hdt * vx1
        my1 = y1 - hdt * vy1
        mx2 = x2 - hdt * vx2
        my2 = y2 - hdt * vy2
        ta = (mx1 - mx0) * (my2 - my0) - (mx2 - mx0) * (my1 - my0)
        tn = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        ok = (ta > 0.0) & (tn > 0.0)
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
        a = hdt * w
        den = 1.0 / (1.0 + a * a)
        cs = (1.0 - a * a) * den
        sn = 2.0 * a * den
        rxx = cs * cs * sxx + 2.0 * cs * sn * sxy + sn * sn * syy
        ryy = sn * sn * sxx - 2.0 * cs * sn * sxy + cs * cs * syy
        rxy = -cs * sn * sxx + (cs * cs - sn * sn) * sxy + cs * sn * syy
        sy = inp[17 * ROW + j] if screen else sy0 + H * ep
        # elastic predictor + radial return (j2_return, with selects)
        tr = (dxx + dyy + dzz) * dt
        txx = rxx + lam * tr + 2.0 * G * dxx * dt
        tyy = ryy + lam * tr + 2.0 * G * dyy * dt
        tzz = szz + lam * tr + 2.0 * G * dzz * dt
        txy = rxy + 2.0 * G * dxy * dt
        p = (txx + tyy + tzz) / 3.0
        exx = txx - p
        eyy = tyy - p
        ezz = tzz - p
        qm = math.sqrt(1.5 * (exx * exx + eyy * eyy + ezz * ezz + 2.0 * txy * txy))
        plastic = qm > sy
        dep = (qm - sy) / (3.0 * G + H) if plastic else 0.0
        fac = 1.0 - 3.0 * G * dep / qm if plastic else 1.0
        nxx = exx * fac + p if plastic else txx
        nyy = eyy * fac + p if plastic else tyy
        nzz = ezz * fac + p if plastic else tzz
        nxy = txy * fac if plastic else txy
        status = ST_DONE if ok else ST_INVERTED
        status = ST_REDO if ok & screen & plastic else status
        if mode == MODE_PLANE_STRESS:
            tol = 1e-12 * (sy + abs(nxx) + abs(nyy))
            redo = plastic & (abs(nzz) > tol)
            status = ST_REDO if ok & redo else status
            nzz = 0.0
        out[0 * ROW + j] = nxx
        out[1 * ROW + j] = nyy
        out[2 * ROW + j] = nzz
        out[3 * ROW + j] = nxy
        out[4 * ROW + j] = ep + dep
        l01 = (x1 - x0) * (x1 - x0) + (y1 - y0) * (y1 - y0)
        l12 = (x2 - x1) * (x2 - x1) + (y2 - y1) * (y2 - y1)
        l20 = (x0 - x2) * (x0 - x2) + (y0 - y2) * (y0 - y2)
        le = tn / math.sqrt(max(l01, max(l12, l20)))
        trd = dxx + dyy + dzz
        comp = bulk & (trd < 0.0)
        q1 = b1 * rho * c * le * (-trd) if bulk else 0.0
        q2 = rho * (b2 * le * trd) * (b2 * le * trd) if comp else 0.0
        q = q1 + q2
        xi = (b1 + (b2 * b2 * le / c * (-trd) if comp else 0.0)) if bulk else 0.0
        out[12 * ROW + j] = le / c * (math.sqrt(1.0 + xi * xi) - xi)
        if mode == MODE_AXISYMMETRIC:
            volm = twopi * (mx0 + mx1 + mx2) / 3.0 * 0.5 * ta
            vol = twopi * (x0 + x1 + x2) / 3.0 * 0.5 * tn
        else:
            volm = thick * 0.5 * ta
            vol = thick * 0.5 * tn
        out[13 * ROW + j] = (sy + H * dep) * dep * volm
        if mode == MODE_PLANE_STRESS:
            out[14 * ROW + j] = -q * (dxx + dyy) * volm * dt
        else:
            out[14 * ROW + j] = -q * trd * volm * dt
        sx = nxx - q
        sy_ = nyy - q
        inv = vol / tn
        gx0 = (y1 - y2) * inv
        gx1 = (y2 - y0) * inv
        gx2 = (y0 - y1) * inv
        gy0 = (x2 - x1) * inv
        gy1 = (x0 - x2) * inv
        gy2 = (x1 - x0) * inv
        out[5 * ROW + j] = sx * gx0 + nxy * gy0
        out[6 * ROW + j] = nxy * gx0 + sy_ * gy0
        out[7 * ROW + j] = sx * gx1 + nxy * gy1
        out[8 * ROW + j] = nxy * gx1 + sy_ * gy1
        out[9 * ROW + j] = sx * gx2 + nxy * gy2
        out[10 * ROW + j] = nxy * gx2 + sy_ * gy2
        if mode == MODE_AXISYMMETRIC:
            out[11 * ROW + j] = twopi * 0.5 * tn * (nzz - q) / 3.0
        else:
            out[11 * ROW + j] = 0.0
        out[15 * ROW + j] = status


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def add_chunk_part(part, dtmin, wp, wv, bad):
    """A chunk's partial results (``part``: its smallest critical step (s), plastic and viscous dissipation
    (J), its first inverted cell or -1) added to the running ones (``dtmin``, ``wp``, ``wv``, ``bad``), chunk
    after chunk in chunk order: the serial kernels and the threaded ones (any thread count) sum the same
    partials in the same order, so they give the same bits. Returns the new (dtmin, wp, wv, bad)."""
    if part[3] >= 0.0 and bad < 0.0:
        bad = part[3]
    return min(dtmin, part[0]), wp + part[1], wv + part[2], bad
