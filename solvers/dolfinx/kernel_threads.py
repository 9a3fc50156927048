"""The explicit steps on several threads (``ExplicitSolver(threads=n)``): the whole step loop is
one compiled numba ``parallel`` function, :func:`run_steps_threaded`.

The element kernel: the cells go in fixed chunks of :func:`.kernels.chunk_size` (a task each) through
:func:`.kernels.element_chunk`. A node whose cells all lie in one chunk gets its forces added by
that chunk's task, in cell order; for a node shared by chunks the forces are stored per cell and
gathered afterwards in cell order (a node-to-cell map built once, :func:`force_map`); the chunks'
dissipation sums are added in chunk order. The node phases (velocities, positions, f = f_ext -
f_int, a = f / m, the wall reactions) are element-wise, split over the threads by node; the sums
(external work, kinetic energies), constraints, kinetic damping, walls' contact and soft contact stay
on one thread in their serial order. So the results do not depend on the number of threads: they
are the serial path's (:func:`.block.run_steps`) bit for bit.

numba 0.56 cannot load from its cache a compiled caller of a ``parallel`` function (the process
crashed), so :func:`run_steps_threaded` is called from Python only and calls the serial compiled
phases of :mod:`.block`, never the other way round.
"""
from __future__ import annotations

from collections import namedtuple

import numba
import numpy as np

from .block import (EV_DT, EV_INVERTED, EV_NONE, SC, _apply_walls, _constrain, _contact,
                    _kinetic_peak)
from .element_math import MODE_AXISYMMETRIC, P_MODE, add_chunk_part
from .kernels import WORK_SIZE, chunk_size, element_chunk
from .reductions import np_sum

__all__ = ["force_map", "ThreadArrays", "thread_arrays", "run_steps_threaded"]

_T, _NSTEP, _DTP, _DTC, _PL, _VI, _EXT, _WALL, _KD = (SC[k] for k in (
    "time", "step_count", "dt_prev", "dt_crit", "plastic_J", "viscous_J", "external_work_J",
    "wall_dissipated_J", "kinetic_damping_J"))
_KDON, _NCONTACT = SC["kinetic_damping"], SC["n_contact"]

#: The threaded path's arrays for the bodies of a block (:func:`thread_arrays`): body ``ib``'s
#: chunks are ``chunk_off[ib]:chunk_off[ib+1]`` (rows of ``work`` (chunks, WORK_SIZE) and ``parts``
#: (chunks, 4), a scratch and a result row per chunk); ``shared`` flags the node rows shared by
#: chunks, ``gather[gather_off[ib]:gather_off[ib+1]]`` are body ``ib``'s; ``fe`` (cells, 7) the
#: per-cell forces of cells with a shared node; ``off, ent`` the block's :func:`force_map`.
ThreadArrays = namedtuple("ThreadArrays", ["chunk_off", "shared", "gather_off", "gather", "fe",
                                           "off", "ent", "work", "parts"])


def force_map(cells: np.ndarray, n_nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Node-to-cell map of the force gather: for node i, ``ent[off[i]:off[i+1]]`` are
    ``7 * cell + 2 * local`` (the cell's row in the per-cell force array flattened, and the node's
    pair of columns in it), in cell order.

    Parameters
    ----------
    cells : int array (nc, 3)
        Node rows of each triangle, < ``n_nodes``.
    n_nodes : int
        Number of node rows.
    """
    nc = len(cells)
    cell = np.repeat(np.arange(nc, dtype=np.int64), 3)
    local = np.tile(np.arange(3, dtype=np.int64), nc)
    node = np.asarray(cells, dtype=np.int64).reshape(-1)
    order = np.lexsort((cell, node))               # by node, then by cell
    off = np.zeros(n_nodes + 1, np.int64)
    np.add.at(off, node + 1, 1)
    return np.cumsum(off), (7 * cell + 2 * local)[order]


def thread_arrays(B) -> ThreadArrays:
    """:class:`ThreadArrays` for the block arrays ``B`` (:class:`.block.BodyArrays`)."""
    nn, nc, nb = len(B.x), len(B.cells), len(B.node_off) - 1
    off, ent = force_map(B.cells, nn)
    shared = np.zeros(nn, np.uint8)
    chunk_off, gather = [0], []
    for ib in range(nb):
        n0, n1 = int(B.node_off[ib]), int(B.node_off[ib + 1])
        c0, c1 = int(B.cell_off[ib]), int(B.cell_off[ib + 1])
        cs = chunk_size(c1 - c0)
        chunk = np.repeat(np.arange(c1 - c0) // cs, 3)
        nodes = B.cells[c0:c1].ravel() - n0
        first = np.full(n1 - n0, np.iinfo(np.int64).max)
        last = np.full(n1 - n0, -1)
        np.minimum.at(first, nodes, chunk)
        np.maximum.at(last, nodes, chunk)
        shared[n0:n1] = first != last
        gather.append(n0 + np.flatnonzero(first != last).astype(np.int64))
        chunk_off.append(chunk_off[-1] + max(1, -(-(c1 - c0) // cs)))
    shared.flags.writeable = False  # the serial kernel's constant is read-only: one compiled element_chunk
    return ThreadArrays(chunk_off=np.array(chunk_off, np.int64), shared=shared,
                        gather_off=np.cumsum([0] + [len(g) for g in gather]).astype(np.int64),
                        gather=np.concatenate(gather), fe=np.zeros((max(nc, 1), 7)), off=off,
                        ent=ent, work=np.zeros((chunk_off[-1], WORK_SIZE)),
                        parts=np.zeros((chunk_off[-1], 4)))


@numba.njit(cache=True, parallel=True)
def run_steps_threaded(B, W, C, sc, dt, n_steps, ev, evf, T):
    """:func:`.block.run_steps` on the threads numba has (``numba.set_num_threads``): ``n_steps``
    steps of ``dt`` (s), the same operations in the same order, the same results bit for bit;
    stops at the first event (``ev``). ``T``: :class:`ThreadArrays`. Returns the steps done."""
    nb = B.node_off.shape[0] - 1
    nn = B.x.shape[0]
    x, v, a, f, m, fext, tmp = B.x, B.v, B.a, B.f, B.m, B.fext, B.tmp
    w_on, w_push, w_fn = W.on, W.push, W.fn
    shared, gather, off, ent, work, parts = T.shared, T.gather, T.off, T.ent, T.work, T.parts
    fef = T.fe.reshape(-1)
    for k in range(n_steps):
        # --- block.step_begin
        if dt > sc[_DTC] * (1 + 1e-12):
            ev[0] = EV_DT
            return k
        dt_avg = 0.5 * (sc[_DTP] + dt)
        t_new = sc[_T] + dt
        wext = 0.0
        for ib in range(nb):
            n0 = B.node_off[ib]
            n1 = B.node_off[ib + 1]
            for i in numba.prange(n0, n1):
                v[i, 0] += dt_avg * a[i, 0]
                v[i, 1] += dt_avg * a[i, 1]
            _constrain(B, ib)
            if sc[_KDON] > 0.0:
                sc[_KD] += _kinetic_peak(B, ib, sc)
            if B.fext_on[ib]:
                for i in numba.prange(n0, n1):
                    tmp[2 * (i - n0)] = v[i, 0] * fext[i, 0]
                    tmp[2 * (i - n0) + 1] = v[i, 1] * fext[i, 1]
                wext += dt * np_sum(tmp, 2 * (n1 - n0))
            for i in numba.prange(n0, n1):
                x[i, 0] += dt * v[i, 0]
                x[i, 1] += dt * v[i, 1]
        sc[_WALL] += _apply_walls(B, W, sc)
        sc[_EXT] += wext
        sc[_T] = t_new
        # --- element forces per body (block._forces, block.after_kernel)
        for i in numba.prange(nn):
            f[i, 0] = 0.0
            f[i, 1] = 0.0
        dtc = np.inf
        for ib in range(nb):
            c0 = B.cell_off[ib]
            c1 = B.cell_off[ib + 1]
            nc = c1 - c0
            k0 = T.chunk_off[ib]
            cells = B.cells[c0:c1]
            stress = B.stress[c0:c1]
            eps_p = B.eps_p[c0:c1]
            temp = B.temp[c0:c1]
            fe = T.fe[c0:c1]
            prm = B.prm[ib]
            k1 = T.chunk_off[ib + 1]
            cs = chunk_size(nc)
            for q in numba.prange(k1 - k0):
                element_chunk(cells, x, v, dt, prm, stress, eps_p, f, fe, shared,
                              q * cs, min(nc, (q + 1) * cs), work[k0 + q], parts[k0 + q], temp)
            axi = int(prm[P_MODE]) == MODE_AXISYMMETRIC
            g0 = T.gather_off[ib]
            g1 = T.gather_off[ib + 1]
            for g in numba.prange(g0, g1):
                i = gather[g]
                fx = f[i, 0]
                fy = f[i, 1]
                for j in range(off[i], off[i + 1]):
                    e = ent[j]
                    fx += fef[e]
                    fy += fef[e + 1]
                    if axi:
                        fx += fef[e - e % 7 + 6]
                f[i, 0] = fx
                f[i, 1] = fy
            d = 1e300
            wp = 0.0
            wv = 0.0
            bad = -1.0
            for q in range(k0, T.chunk_off[ib + 1]):
                d, wp, wv, bad = add_chunk_part(parts[q], d, wp, wv, bad)
            if bad >= 0.0:
                ev[0] = EV_INVERTED
                ev[1] = ib
                ev[2] = int(bad)
                return k
            sc[_PL] += 0.0 + wp
            sc[_VI] += 0.0 + wv
            n0 = B.node_off[ib]
            n1 = B.node_off[ib + 1]
            if B.fext_on[ib]:
                for i in numba.prange(n0, n1):
                    f[i, 0] = -f[i, 0] + fext[i, 0]
                    f[i, 1] = -f[i, 1] + fext[i, 1]
            else:
                for i in numba.prange(n0, n1):
                    f[i, 0] = -f[i, 0]
                    f[i, 1] = -f[i, 1]
            dtc = min(dtc, d)
        # --- block.forces_end
        sc[_DTC] = dtc
        if sc[_NCONTACT] > 0:
            _contact(C, B, sc, dt, ev, evf)
            if ev[0] != EV_NONE:
                return k
        for ib in range(nb):
            n0 = B.node_off[ib]
            n1 = B.node_off[ib + 1]
            for iw in range(W.point.shape[0]):
                if not W.acts[iw, ib]:
                    continue
                wn0 = W.normal[iw, 0]
                wn1 = W.normal[iw, 1]
                sliding = W.sliding[iw]
                for i in numba.prange(n0, n1):
                    w_push[iw, i] = 0
                    if w_on[iw, i]:
                        fn = f[i, 0] * wn0 + f[i, 1] * wn1
                        if fn < 0.0:
                            w_push[iw, i] = 1
                            w_fn[iw, i] = fn
                            if sliding:
                                f[i, 0] -= fn * wn0
                                f[i, 1] -= fn * wn1
                            else:
                                f[i, 0] = 0.0
                                f[i, 1] = 0.0
            for i in numba.prange(n0, n1):
                a[i, 0] = f[i, 0] / m[i]
                a[i, 1] = f[i, 1] / m[i]
            af = a.reshape(-1)
            for j in range(B.cidx_off[ib], B.cidx_off[ib + 1]):
                af[B.cidx[j]] = 0.0
        sc[_DTP] = dt
        sc[_NSTEP] += 1
    return n_steps
