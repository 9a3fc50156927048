"""Compiled explicit steps: n central-difference steps entirely in numba (element kernel, internal
force scatter, soft contact with a bucket search, friction, contact viscosity, rigid walls,
kinetic damping, the energy ledger), on the arrays packed by :mod:`.block_data`.

Every operation repeats the Python path of :class:`~.solver.ExplicitSolver` (``_step``) in the
same order and with the same rounding (numpy-like sums from :mod:`.reductions`), so that the two
give the same bits. Events (a step above the critical one, an inverted cell, a penetration) stop
the loop and are reported through ``ev`` / ``evf`` for the caller to raise.
"""
from __future__ import annotations

from collections import namedtuple

import numba
import numpy as np

from .contact_kernel import contact_pass, surface_geometry
from .kernels import element_step
from .reductions import np_sum

__all__ = ["BodyArrays", "WallArrays", "run_steps", "step", "step_begin", "after_kernel",
           "forces_end", "switch_forces",
           "follower_pressure", "EV_NONE", "EV_DT", "EV_INVERTED", "SC"]

EV_NONE = 0
EV_DT = 1
EV_INVERTED = 2

#: indices into the scalar state array ``sc``
SC = dict(time=0, step_count=1, dt_prev=2, dt_crit=3, plastic_J=4, viscous_J=5, external_work_J=6,
          wall_dissipated_J=7, kinetic_damping_J=8, contact_work=9, contact_stored=10,
          kinetic_damping=11, wall_tol=12, axisymmetric=13, thickness=14, cfl=15, n_contact=16)
N_SC = 17
_T, _NSTEP, _DTP, _DTC, _PL, _VI, _EXT, _WALL, _KD, _CW, _CS, _KDON, _WTOL, _AXI, _THK = range(15)
_NCONTACT = 16

#: Nodal and cell arrays of every body, concatenated (see ``block_data.build_bodies``).
BodyArrays = namedtuple("BodyArrays", [
    "node_off", "cell_off", "cells", "prm", "x", "v", "a", "m", "f", "fext", "fext_on",
    "stress", "eps_p", "temp", "con_off", "con_idx", "con_val", "cidx_off", "cidx", "ke_half", "tmp",
    "acc", "work"])

#: Rigid walls: their planes, the bodies they act on, and per-node scratch.
WallArrays = namedtuple("WallArrays", ["point", "normal", "sliding", "acts", "order", "on", "fn",
                                       "push", "hits"])


@numba.njit(cache=True)
def _constrain(B, ib):
    """Prescribed velocity components (constant values; the axis last) of body ``ib``."""
    vf = B.v.reshape(-1)
    for j in range(B.con_off[ib], B.con_off[ib + 1]):
        vf[B.con_idx[j]] = B.con_val[j]


@numba.njit(cache=True)
def _half_ke(B, n0, n1):
    """sum m v^2 over nodes n0..n1 (as np.sum(m[:, None] * v ** 2))."""
    k = 0
    for i in range(n0, n1):
        B.tmp[k] = B.m[i] * (B.v[i, 0] * B.v[i, 0])
        B.tmp[k + 1] = B.m[i] * (B.v[i, 1] * B.v[i, 1])
        k += 2
    return np_sum(B.tmp, k)


@numba.njit(cache=True)
def _ke_estimate(B, n0, n1, hdt):
    """sum m (v + dt/2 a)^2 over nodes n0..n1."""
    k = 0
    for i in range(n0, n1):
        for c in range(2):
            w = B.v[i, c] + hdt * B.a[i, c]
            B.tmp[k] = B.m[i] * (w * w)
            k += 1
    return np_sum(B.tmp, k)


@numba.njit(cache=True)
def switch_forces(B, sc, new):
    """Make ``new`` (N, 2) the held external forces from now on: a^n includes them, and the change
    of the kinetic-energy estimate is booked as external work (as ``ExplicitSolver.advance``)."""
    hdt = 0.5 * sc[_DTP]
    nb = B.node_off.shape[0] - 1
    for ib in range(nb):
        n0 = B.node_off[ib]
        n1 = B.node_off[ib + 1]
        changed = False
        nonzero = False
        for i in range(n0, n1):
            for c in range(2):
                if new[i, c] - B.fext[i, c] != 0.0:
                    changed = True
                if new[i, c] != 0.0:
                    nonzero = True
        if changed:
            ke_old = _ke_estimate(B, n0, n1, hdt)
            for i in range(n0, n1):
                for c in range(2):
                    B.a[i, c] += (new[i, c] - B.fext[i, c]) / B.m[i]
            af = B.a.reshape(-1)
            for j in range(B.cidx_off[ib], B.cidx_off[ib + 1]):
                af[B.cidx[j]] = 0.0
            ke_new = _ke_estimate(B, n0, n1, hdt)
            sc[_EXT] += 0.5 * (ke_new - ke_old)
        for i in range(n0, n1):
            B.fext[i, 0] = new[i, 0]
            B.fext[i, 1] = new[i, 1]
        B.fext_on[ib] = 1 if nonzero else 0


@numba.njit(cache=True)
def _kinetic_peak(B, ib, sc):
    """Kinetic damping of body ``ib`` (as ``ExplicitSolver._kinetic_peak``): once its half-step
    kinetic energy has passed a peak, zero its velocities (prescribed ones re-applied); returns
    the kinetic energy removed, J."""
    n0 = B.node_off[ib]
    n1 = B.node_off[ib + 1]
    ke = 0.5 * _half_ke(B, n0, n1)
    if ke >= B.ke_half[ib]:
        B.ke_half[ib] = ke
        return 0.0
    for i in range(n0, n1):
        B.v[i, 0] = 0.0
        B.v[i, 1] = 0.0
    _constrain(B, ib)
    B.ke_half[ib] = 0.0
    return ke - 0.5 * _half_ke(B, n0, n1)


@numba.njit(cache=True)
def _apply_walls(B, W, sc):
    """Put nodes behind a rigid wall back on it and remove their (normal) velocity; mark the nodes
    on the wall (``W.on``) for the reactions. Returns the kinetic energy removed, J."""
    removed = 0.0
    tol = sc[_WTOL]
    nb = B.node_off.shape[0] - 1
    for iw in range(W.point.shape[0]):
        p0 = W.point[iw, 0]
        p1 = W.point[iw, 1]
        n0 = W.normal[iw, 0]
        n1 = W.normal[iw, 1]
        for k in range(nb):
            ib = W.order[iw, k]          # the wall's bodies in its own order (as the Python loop)
            if ib < 0:
                break
            nh = 0
            for i in range(B.node_off[ib], B.node_off[ib + 1]):
                d = (B.x[i, 0] - p0) * n0 + (B.x[i, 1] - p1) * n1
                W.on[iw, i] = 1 if d <= tol else 0
                if d < 0.0:
                    B.x[i, 0] -= d * n0
                    B.x[i, 1] -= d * n1
                    W.hits[nh] = i
                    nh += 1
            if nh == 0:
                continue
            for k in range(nh):
                i = W.hits[k]
                B.tmp[k] = B.m[i] * (B.v[i, 0] * B.v[i, 0] + B.v[i, 1] * B.v[i, 1])
            ke0 = 0.5 * np_sum(B.tmp, nh)
            for k in range(nh):
                i = W.hits[k]
                if W.sliding[iw]:
                    vn = B.v[i, 0] * n0 + B.v[i, 1] * n1
                    B.v[i, 0] -= vn * n0
                    B.v[i, 1] -= vn * n1
                else:
                    B.v[i, 0] = 0.0
                    B.v[i, 1] = 0.0
            for k in range(nh):
                i = W.hits[k]
                B.tmp[k] = B.m[i] * (B.v[i, 0] * B.v[i, 0] + B.v[i, 1] * B.v[i, 1])
            removed += ke0 - 0.5 * np_sum(B.tmp, nh)
    return removed


@numba.njit(cache=True)
def _wall_reactions(B, W, ib):
    """Cancel the force (all of it, or its normal part on a sliding wall) of body ``ib``'s wall
    nodes pushed into the wall; ``W.fn`` / ``W.push`` keep the normal force for the pressures."""
    for iw in range(W.point.shape[0]):
        if not W.acts[iw, ib]:
            continue
        n0 = W.normal[iw, 0]
        n1 = W.normal[iw, 1]
        for i in range(B.node_off[ib], B.node_off[ib + 1]):
            W.push[iw, i] = 0
            if not W.on[iw, i]:
                continue
            fn = B.f[i, 0] * n0 + B.f[i, 1] * n1
            if fn < 0.0:
                W.push[iw, i] = 1
                W.fn[iw, i] = fn
                if W.sliding[iw]:
                    B.f[i, 0] -= fn * n0
                    B.f[i, 1] -= fn * n1
                else:
                    B.f[i, 0] = 0.0
                    B.f[i, 1] = 0.0


@numba.njit(cache=True)
def _contact(C, B, sc, dt, ev, evf):
    """All contact passes, then the forces into ``B.f`` and the trapezoidal work of the step."""
    surface_geometry(C, B.x, B.v, sc[_AXI] > 0.0, sc[_THK])
    C.fs[:] = 0.0
    stored = 0.0
    for p in range(C.p_slave.shape[0]):
        stored += contact_pass(C, p, dt, ev, evf)
        if ev[0] != EV_NONE:
            return
    work = 0.0
    for s in range(C.node_off.shape[0] - 1):
        k = 0
        for i in range(C.node_off[s], C.node_off[s + 1]):
            r = C.rows[i]
            B.f[r, 0] += C.fs[i, 0]
            B.f[r, 1] += C.fs[i, 1]
            for c in range(2):
                C.work[k] = C.vs[i, c] * 0.5 * (C.fs_prev[i, c] + C.fs[i, c])
                k += 1
        if dt > 0:
            work += dt * np_sum(C.work, k)
        for i in range(C.node_off[s], C.node_off[s + 1]):
            C.fs_prev[i, 0] = C.fs[i, 0]
            C.fs_prev[i, 1] = C.fs[i, 1]
    sc[_CW] += work
    sc[_CS] = stored


@numba.njit(cache=True)
def after_kernel(B, sc, ib, d, dtc, ev):
    """Body ``ib``'s element kernel has added its internal forces to ``B.f`` and its dissipation
    to ``B.acc`` (critical step ``d``, s): book them, f = f_ext - f_int on its nodes. Returns the
    smallest critical step so far (``dtc``, s); an inverted cell is an event."""
    if B.acc[2] >= 0:
        ev[0] = EV_INVERTED
        ev[1] = ib
        ev[2] = int(B.acc[2])
        return dtc
    sc[_PL] += B.acc[0]
    sc[_VI] += B.acc[1]
    n0 = B.node_off[ib]
    n1 = B.node_off[ib + 1]
    for i in range(n0, n1):
        B.f[i, 0] = -B.f[i, 0]
        B.f[i, 1] = -B.f[i, 1]
    if B.fext_on[ib]:
        for i in range(n0, n1):
            B.f[i, 0] += B.fext[i, 0]
            B.f[i, 1] += B.fext[i, 1]
    return min(dtc, d)


@numba.njit(cache=True)
def forces_end(B, W, C, sc, dt, dtc, ev, evf):
    """After every body's element forces: the critical step, contact and wall forces; a = f / m."""
    sc[_DTC] = dtc
    if sc[_NCONTACT] > 0:
        _contact(C, B, sc, dt, ev, evf)
        if ev[0] != EV_NONE:
            return
    for ib in range(B.node_off.shape[0] - 1):
        _wall_reactions(B, W, ib)
        for i in range(B.node_off[ib], B.node_off[ib + 1]):
            B.a[i, 0] = B.f[i, 0] / B.m[i]
            B.a[i, 1] = B.f[i, 1] / B.m[i]
        af = B.a.reshape(-1)
        for j in range(B.cidx_off[ib], B.cidx_off[ib + 1]):
            af[B.cidx[j]] = 0.0


@numba.njit(cache=True)
def _forces(B, W, C, sc, dt, ev, evf):
    """Internal (element kernel), external, contact and wall forces; a = f / m."""
    B.f[:] = 0.0
    dtc = np.inf
    for ib in range(B.node_off.shape[0] - 1):
        c0 = B.cell_off[ib]
        c1 = B.cell_off[ib + 1]
        B.acc[:] = 0.0
        d = element_step(B.cells[c0:c1], B.x, B.v, dt, B.prm[ib], B.stress[c0:c1],
                         B.eps_p[c0:c1], B.f, B.acc, B.work, B.temp[c0:c1])
        dtc = after_kernel(B, sc, ib, d, dtc, ev)
        if ev[0] != EV_NONE:
            return
    forces_end(B, W, C, sc, dt, dtc, ev, evf)


@numba.njit(cache=True)
def step_begin(B, W, sc, dt, ev):
    """The step up to the forces: v^{n+1/2}, constraints, kinetic damping, external work, x^{n+1},
    rigid walls, t^{n+1}; a step above the critical one is an event (nothing done)."""
    if dt > sc[_DTC] * (1 + 1e-12):
        ev[0] = EV_DT
        return
    dt_avg = 0.5 * (sc[_DTP] + dt)
    t_new = sc[_T] + dt
    wext = 0.0
    nb = B.node_off.shape[0] - 1
    for ib in range(nb):
        n0 = B.node_off[ib]
        n1 = B.node_off[ib + 1]
        for i in range(n0, n1):
            B.v[i, 0] += dt_avg * B.a[i, 0]
            B.v[i, 1] += dt_avg * B.a[i, 1]
        _constrain(B, ib)
        if sc[_KDON] > 0.0:
            sc[_KD] += _kinetic_peak(B, ib, sc)
        if B.fext_on[ib]:
            k = 0
            for i in range(n0, n1):
                B.tmp[k] = B.v[i, 0] * B.fext[i, 0]
                B.tmp[k + 1] = B.v[i, 1] * B.fext[i, 1]
                k += 2
            wext += dt * np_sum(B.tmp, k)
        for i in range(n0, n1):
            B.x[i, 0] += dt * B.v[i, 0]
            B.x[i, 1] += dt * B.v[i, 1]
    sc[_WALL] += _apply_walls(B, W, sc)
    sc[_EXT] += wext
    sc[_T] = t_new


@numba.njit(cache=True)
def step(B, W, C, sc, dt, ev, evf):
    """One explicit step of size ``dt`` (s); ``ev[0]`` != 0 reports an event."""
    step_begin(B, W, sc, dt, ev)
    if ev[0] != EV_NONE:
        return
    _forces(B, W, C, sc, dt, ev, evf)
    if ev[0] != EV_NONE:
        return
    sc[_DTP] = dt
    sc[_NSTEP] += 1


@numba.njit(cache=True)
def run_steps(B, W, C, sc, dt, n_steps, ev, evf):
    """``n_steps`` steps of size ``dt`` (s); stops at the first event. Returns the steps done."""
    for k in range(n_steps):
        step(B, W, C, sc, dt, ev, evf)
        if ev[0] != EV_NONE:
            return k
    return n_steps


@numba.njit(cache=True)
def follower_pressure(x, segs, s0, s1, n0, n1, p, axisym, thickness, acc0, acc1, out, assign):
    """Consistent nodal forces (N) of a uniform follower pressure ``p`` (Pa, positive pushes into
    the body) on the segments ``segs[s0:s1]`` (node rows into ``x``, body on the left) at the
    current positions ``x`` (m), rounded as :meth:`.body.Body.pressure_forces` (per-node sums in
    segment order, like ``np.bincount``; planar: times ``thickness``; axisymmetric: 2 pi ring).

    Rows ``n0:n1`` (the body's nodes) of ``out`` receive the forces (``assign``) or have them
    added (a further load on the same body); ``acc0`` / ``acc1`` are (N, 2) scratch.
    """
    for i in range(n0, n1):
        acc0[i, 0] = 0.0
        acc0[i, 1] = 0.0
        acc1[i, 0] = 0.0
        acc1[i, 1] = 0.0
    twopi = 2 * np.pi
    for s in range(s0, s1):
        a = segs[s, 0]
        b = segs[s, 1]
        t0 = x[b, 0] - x[a, 0]
        t1 = x[b, 1] - x[a, 1]
        ln = np.sqrt(t0 * t0 + t1 * t1)
        nx = t1 / ln
        ny = -t0 / ln
        if axisym:
            wa = twopi * ln * (2 * x[a, 0] + x[b, 0]) / 6.0
            wb = twopi * ln * (x[a, 0] + 2 * x[b, 0]) / 6.0
        else:
            wa = 0.5 * ln * thickness
            wb = wa
        acc0[a, 0] += wa * nx
        acc0[a, 1] += wa * ny
        acc1[b, 0] += wb * nx
        acc1[b, 1] += wb * ny
    for i in range(n0, n1):
        for c in range(2):
            f = 0.0 - p * (acc0[i, c] + acc1[i, c])
            if assign:
                out[i, c] = f
            else:
                out[i, c] = out[i, c] + f
