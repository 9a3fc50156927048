"""The explicit steps with the element kernel on several threads (``ExplicitSolver(threads=n)``).

The cells go in fixed chunks of :data:`.kernels.CHUNK` (a task each) through
:func:`.kernels.element_chunk`. A node whose cells all lie in one chunk gets its forces added by
that chunk's task, in cell order; for a node shared by chunks the forces are stored per cell and
gathered afterwards in cell order (a node-to-cell map built once, :func:`force_map`); the chunks'
dissipation sums are added in chunk order. These are the serial kernel's sums in the serial order:
the results do not depend on the number of threads, they are the serial results bit for bit.

The threaded kernel is a top-level numba ``parallel`` function called from Python once per body
and step (:func:`run_steps_threaded`), between the compiled step phases of :mod:`.block`: numba
0.56 cannot load from its cache a compiled caller of a ``parallel`` function (the process crashed),
so the step loop of the threaded path is in Python (a few calls per step, ~10 us each: use it for
meshes of 10^4 cells and more, on cores no other process uses).
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from .block import EV_NONE, SC, after_kernel, forces_end, step_begin
from .element_math import MODE_AXISYMMETRIC, P_MODE
from .kernels import CHUNK, WORK_SIZE, element_chunk

__all__ = ["force_map", "ThreadArrays", "element_step_threaded", "run_steps_threaded"]

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


@dataclass
class ThreadArrays:
    """Per body: its cells' slices of the block arrays, the nodes shared by chunks (a flag per
    node row of the block, and their body-local indices), per-cell forces (nc, 7), the
    :func:`force_map` (body-local node indices), a scratch and a result row per chunk, the
    body's first node row."""

    cells: list
    shared: list
    gather: list
    stress: list
    eps_p: list
    fe: list
    off: list
    ent: list
    work: list
    parts: list
    n0: list

    @classmethod
    def build(cls, B) -> "ThreadArrays":
        """The arrays for the bodies of the block arrays ``B`` (:class:`.block.BodyArrays`)."""
        t = cls(*([] for _ in range(11)))
        for ib in range(len(B.node_off) - 1):
            n0, n1 = int(B.node_off[ib]), int(B.node_off[ib + 1])
            c0, c1 = int(B.cell_off[ib]), int(B.cell_off[ib + 1])
            cells = B.cells[c0:c1]
            off, ent = force_map(cells - n0, n1 - n0)
            nch = max(1, -(-(c1 - c0) // CHUNK))
            t.cells.append(cells)
            chunk = np.arange(c1 - c0) // CHUNK
            first = np.full(n1 - n0, np.iinfo(np.int64).max)
            last = np.full(n1 - n0, -1)
            np.minimum.at(first, cells.ravel() - n0, np.repeat(chunk, 3))
            np.maximum.at(last, cells.ravel() - n0, np.repeat(chunk, 3))
            sh = np.zeros(len(B.x), np.uint8)          # node rows of the block
            sh[n0:n1] = first != last
            t.shared.append(sh)
            t.gather.append(np.flatnonzero(first != last).astype(np.int64))
            t.stress.append(B.stress[c0:c1])
            t.eps_p.append(B.eps_p[c0:c1])
            t.fe.append(np.zeros((max(c1 - c0, 1), 7)))
            t.off.append(off)
            t.ent.append(ent)
            t.work.append(np.zeros((nch, WORK_SIZE)))
            t.parts.append(np.zeros((nch, 4)))
            t.n0.append(n0)
        return t


@numba.njit(cache=True, error_model="numpy")
def _gather(off, ent, fe, f_int, n0, nodes, axi):
    """f_int[n0 + i] += the forces of node i's cells in cell order, for i in ``nodes`` (no
    fast-math: the serial kernel's order of additions)."""
    fef = fe.reshape(-1)
    for i in nodes:
        fx = f_int[n0 + i, 0]
        fy = f_int[n0 + i, 1]
        for j in range(off[i], off[i + 1]):
            e = ent[j]
            fx += fef[e]
            fy += fef[e + 1]
            if axi:
                fx += fef[e - e % 7 + 6]
        f_int[n0 + i, 0] = fx
        f_int[n0 + i, 1] = fy


@numba.njit(cache=True, parallel=True, error_model="numpy")
def element_step_threaded(cells, x, v, dt, prm, stress, eps_p, f_int, acc, shared, gather, fe,
                          off, ent, work, parts, n0):
    """:func:`.kernels.element_step` on the threads numba has (``numba.set_num_threads``), with the
    same arguments and results (bit for bit) plus (see :class:`ThreadArrays`): ``shared`` the flag
    per node row of the nodes shared by chunks, ``gather`` their indices from ``n0``, ``fe`` (nc, 7)
    per-cell forces, ``off, ent`` the :func:`force_map` of these cells (node indices from ``n0``),
    ``work`` (chunks, WORK_SIZE) and ``parts`` (chunks, 4) a scratch and a result row per chunk."""
    nc = cells.shape[0]
    nch = (nc + CHUNK - 1) // CHUNK
    for k in numba.prange(nch):
        element_chunk(cells, x, v, dt, prm, stress, eps_p, f_int, fe, shared, k * CHUNK,
                      min(nc, (k + 1) * CHUNK), work[k], parts[k])
    axi = int(prm[P_MODE]) == MODE_AXISYMMETRIC
    _gather(off, ent, fe, f_int, n0, gather, axi)   # few nodes: one thread
    dtmin = 1e300
    wp = 0.0
    wv = 0.0
    acc[2] = -1.0
    for k in range(nch):
        dtmin = min(dtmin, parts[k, 0])
        wp += parts[k, 1]
        wv += parts[k, 2]
        if parts[k, 3] >= 0.0 and acc[2] < 0.0:
            acc[2] = parts[k, 3]
    acc[0] += wp
    acc[1] += wv
    return dtmin


def run_steps_threaded(B, W, C, sc, dt: float, n_steps: int, ev, evf, T: ThreadArrays) -> int:
    """:func:`.block.run_steps` with the threaded element kernel: ``n_steps`` steps of ``dt`` (s),
    the same phases in the same order; stops at the first event. Returns the steps done."""
    dt_slot, count_slot = SC["dt_prev"], SC["step_count"]
    for k in range(n_steps):
        step_begin(B, W, sc, dt, ev)
        if ev[0] != EV_NONE:
            return k
        B.f[:] = 0.0
        dtc = np.inf
        for ib in range(len(T.cells)):
            B.acc[:] = 0.0
            d = element_step_threaded(T.cells[ib], B.x, B.v, dt, B.prm[ib], T.stress[ib],
                                      T.eps_p[ib], B.f, B.acc, T.shared[ib], T.gather[ib], T.fe[ib],
                                      T.off[ib], T.ent[ib], T.work[ib], T.parts[ib], T.n0[ib])
            dtc = after_kernel(B, sc, ib, d, dtc, ev)
            if ev[0] != EV_NONE:
                return k
        forces_end(B, W, C, sc, dt, dtc, ev, evf)
        if ev[0] != EV_NONE:
            return k
        sc[dt_slot] = dt
        sc[count_slot] += 1
    return n_steps
