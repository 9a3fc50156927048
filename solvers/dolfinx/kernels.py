"""Compiled (numba) element kernel of the explicit step: objective stress update, J2 radial return,
bulk viscosity, internal nodal forces and element critical time steps in one pass over the cells, in
vectorised batches (the per-cell mathematics is in :mod:`.element_math`).

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

from .element_math import (BATCH, FM, add_chunk_part, IN_ROWS, MODE_AXISYMMETRIC, MODE_PLANE_STRAIN,
                           MODE_PLANE_STRESS, N_PRM, OUT_ROWS, P_B1, P_B2, P_BULK, P_G, P_H, P_K,
                           P_MODE, P_R1, P_R2, P_RATE, P_RHO, P_SY0, P_THICK, ROW, ST_INVERTED,
                           ST_REDO, batch_update, cell_update, general_material)
from .flow_curves import encode, flow_floor, floor_value
from .kernel_layout import P_BETA, P_FLOW, P_RHOCP, P_SYF, P_T0, P_THERM

__all__ = ["MODE_PLANE_STRESS", "MODE_PLANE_STRAIN", "MODE_AXISYMMETRIC", "pack_parameters",
           "element_step", "element_chunk", "element_critical_dt", "N_PRM", "WORK_SIZE", "CHUNK", "chunk_size"]



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

    Returns
    -------
    float64 array (N_PRM + the flow curve's parameters,)
        The layout of :mod:`.kernel_layout`; the flow curve's own parameters from ``P_FP`` on
        (:func:`.flow_curves.encode`).
    """
    rid, r1, r2 = material.rate_parameters()
    law, fp = encode(material.flow_curve)
    prm = np.zeros(N_PRM + len(fp))
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
    prm[P_FLOW] = law
    prm[P_THERM] = 1.0 if material.specific_heat is not None else 0.0
    prm[P_BETA] = material.taylor_quinney
    prm[P_RHOCP] = material.density * (material.specific_heat or 0.0)
    prm[P_T0] = material.initial_temperature
    prm[N_PRM:] = fp
    prm[P_SYF] = floor_value(prm, 0.0, prm[P_T0])
    return prm


#: length (float64) of the scratch ``work`` of :func:`element_step`
WORK_SIZE = (IN_ROWS + OUT_ROWS) * ROW + OUT_ROWS + 4
#: most cells per chunk: the dissipation sums are taken per chunk, then over the chunks in order, so
#: that the threaded kernel (:mod:`.kernel_threads`, a chunk per task) gives the same bits
CHUNK = 8192
_NO_SHARED = np.zeros(0, np.uint8)  # the serial kernel flags no node (a constant in compiled code)


@numba.njit(cache=True)
def chunk_size(nc):
    """Cells per chunk of a body of ``nc`` cells: at most :data:`CHUNK`, and the chunks (all of one size
    but the last) a power of two in number, so that 2, 4 or 8 threads get equal shares (13 chunks of
    8192 on 2 threads gave one thread 7 and the other 5.25: 87 % of the work balanced). A function of
    ``nc`` alone: the serial and the threaded kernels cut the same chunks whatever the thread count."""
    k = 1
    while k * CHUNK < nc:
        k *= 2
    return max(1, -(-nc // k))


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def element_step(cells, x, v, dt, prm, stress, eps_p, f_int, acc, work, temp):
    """Explicit element update over all ``cells``: batches of ``BATCH`` cells are gathered into a
    structure-of-arrays scratch, updated by the vectorised :func:`.element_math.batch_update`
    (rate-independent materials; a cell that needs the plane-stress secant iteration, and every
    cell of a rate-dependent material, by the scalar :func:`.element_math.cell_update`), and
    scattered back; the nodal forces are added in cell order.

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
    work : float64 array (WORK_SIZE,)
        Scratch.
    temp : float64 array (nc,) or (0,)
        Temperature per cell, K; updated in place by the plastic heating of a material with a
        specific heat. Empty: the material's initial temperature, not updated.
        (Both required: an omitted or None argument would compile a second variant of this kernel
        and of :func:`element_chunk`.)

    Returns
    -------
    float
        Smallest element critical time step (CFL 1, with the bulk-viscosity reduction), s.
    """
    nc = cells.shape[0]
    part = work[WORK_SIZE - 4:]
    no_fe = work[:0].reshape(0, 7)
    dtmin = 1e300
    wp = 0.0
    wv = 0.0
    acc[2] = -1.0
    cs = chunk_size(nc)
    for e0 in range(0, nc, cs):
        element_chunk(cells, x, v, dt, prm, stress, eps_p, f_int, no_fe, _NO_SHARED, e0,
                      min(nc, e0 + cs), work, part, temp)
        dtmin, wp, wv, acc[2] = add_chunk_part(part, dtmin, wp, wv, acc[2])
    acc[0] += wp
    acc[1] += wv
    return dtmin


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
def element_chunk(cells, x, v, dt, prm, stress, eps_p, f_int, fe, shared, e0, e1, work, part, temp):
    """Cells ``e0:e1`` of :func:`element_step`. Their nodal forces are added to ``f_int`` in cell
    order; if ``fe`` has rows (the threaded kernel), those of the nodes flagged in ``shared`` (node
    rows of ``f_int``: nodes whose cells lie in more than one chunk) are stored per cell in ``fe``
    instead (nc, 7: f0x f0y f1x f1y f2x f2y, and the hoop force per node in axisymmetry) for a
    gather. ``part`` receives (smallest critical step s, plastic and bulk-viscous dissipation J
    summed in cell order, first inverted cell or -1). ``temp``: the temperature per cell (K; empty:
    the material's initial temperature, not updated).

    Kernels by material: the linear law without a rate law in vectorised batches
    (:func:`.element_math.batch_update`), with a rate law by the scalar
    :func:`.element_math.cell_update`; a general material (another flow curve, or a temperature)
    screened in the batches (the cells whose trial stress stays below
    :func:`.flow_curves.flow_floor` are elastic) and its other cells by :func:`cell_update`."""
    inp = work[:IN_ROWS * ROW]
    out = work[IN_ROWS * ROW:(IN_ROWS + OUT_ROWS) * ROW]
    one = work[(IN_ROWS + OUT_ROWS) * ROW:(IN_ROWS + OUT_ROWS) * ROW + OUT_ROWS]
    axi = int(prm[P_MODE]) == MODE_AXISYMMETRIC
    general = general_material(prm)
    vector = int(prm[P_RATE]) == 0 or general
    has_t = temp.shape[0] > 0
    t0 = prm[P_T0]
    store = fe.shape[0] > 0
    dtmin = 1e300
    wp = 0.0
    wv = 0.0
    bad = -1.0
    for s in range(e0, e1, BATCH):
        n = min(BATCH, e1 - s)
        for j in range(n):
            e = s + j
            i0 = cells[e, 0]
            i1 = cells[e, 1]
            i2 = cells[e, 2]
            inp[0 * ROW + j] = x[i0, 0]
            inp[1 * ROW + j] = x[i0, 1]
            inp[2 * ROW + j] = x[i1, 0]
            inp[3 * ROW + j] = x[i1, 1]
            inp[4 * ROW + j] = x[i2, 0]
            inp[5 * ROW + j] = x[i2, 1]
            inp[6 * ROW + j] = v[i0, 0]
            inp[7 * ROW + j] = v[i0, 1]
            inp[8 * ROW + j] = v[i1, 0]
            inp[9 * ROW + j] = v[i1, 1]
            inp[10 * ROW + j] = v[i2, 0]
            inp[11 * ROW + j] = v[i2, 1]
            inp[12 * ROW + j] = stress[e, 0]
            inp[13 * ROW + j] = stress[e, 1]
            inp[14 * ROW + j] = stress[e, 2]
            inp[15 * ROW + j] = stress[e, 3]
            inp[16 * ROW + j] = eps_p[e]
            if general:
                tc = temp[e] if has_t else t0
                inp[17 * ROW + j] = flow_floor(prm, eps_p[e], tc)
                inp[18 * ROW + j] = tc
        if vector:
            batch_update(inp, out, n, dt, prm)
        else:
            for j in range(n):
                out[15 * ROW + j] = ST_REDO
        for j in range(n):
            e = s + j
            if out[15 * ROW + j] == ST_REDO:
                cell_update(inp[0 * ROW + j], inp[1 * ROW + j], inp[2 * ROW + j], inp[3 * ROW + j],
                            inp[4 * ROW + j], inp[5 * ROW + j], inp[6 * ROW + j], inp[7 * ROW + j],
                            inp[8 * ROW + j], inp[9 * ROW + j], inp[10 * ROW + j],
                            inp[11 * ROW + j], inp[12 * ROW + j], inp[13 * ROW + j],
                            inp[14 * ROW + j], inp[15 * ROW + j], inp[16 * ROW + j], dt, prm, one,
                            inp[18 * ROW + j] if general else -1.0)
                for r in range(OUT_ROWS):
                    out[r * ROW + j] = one[r]
                if general and has_t and one[15] != ST_INVERTED:
                    temp[e] = one[16]
            if out[15 * ROW + j] == ST_INVERTED:
                if bad < 0.0:
                    bad = e
                if store:
                    for r in range(7):
                        fe[e, r] = 0.0
                continue
            stress[e, 0] = out[0 * ROW + j]
            stress[e, 1] = out[1 * ROW + j]
            stress[e, 2] = out[2 * ROW + j]
            stress[e, 3] = out[3 * ROW + j]
            eps_p[e] = out[4 * ROW + j]
            i0 = cells[e, 0]
            i1 = cells[e, 1]
            i2 = cells[e, 2]
            if store:
                if shared[i0] or shared[i1] or shared[i2]:
                    for r in range(7):
                        fe[e, r] = out[(5 + r) * ROW + j]
                hoop = out[11 * ROW + j] if axi else 0.0
                if not shared[i0]:
                    f_int[i0, 0] += out[5 * ROW + j]
                    f_int[i0, 1] += out[6 * ROW + j]
                    if axi:
                        f_int[i0, 0] += hoop
                if not shared[i1]:
                    f_int[i1, 0] += out[7 * ROW + j]
                    f_int[i1, 1] += out[8 * ROW + j]
                    if axi:
                        f_int[i1, 0] += hoop
                if not shared[i2]:
                    f_int[i2, 0] += out[9 * ROW + j]
                    f_int[i2, 1] += out[10 * ROW + j]
                    if axi:
                        f_int[i2, 0] += hoop
            else:
                f_int[i0, 0] += out[5 * ROW + j]
                f_int[i0, 1] += out[6 * ROW + j]
                f_int[i1, 0] += out[7 * ROW + j]
                f_int[i1, 1] += out[8 * ROW + j]
                f_int[i2, 0] += out[9 * ROW + j]
                f_int[i2, 1] += out[10 * ROW + j]
                if axi:
                    hoop = out[11 * ROW + j]
                    f_int[i0, 0] += hoop
                    f_int[i1, 0] += hoop
                    f_int[i2, 0] += hoop
            dte = out[12 * ROW + j]
            if dte < dtmin:
                dtmin = dte
            wp += out[13 * ROW + j]
            wv += out[14 * ROW + j]
    part[0] = dtmin
    part[1] = wp
    part[2] = wv
    part[3] = bad


@numba.njit(cache=True, error_model="numpy", fastmath=FM)
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
