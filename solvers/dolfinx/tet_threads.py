"""The 3D element kernel on several threads (``ExplicitSolver3D(threads=n)``, issue 31): the
scheme of the 2D threaded kernel (:mod:`.kernel_threads`) for tetrahedra.

A body's cells go in the fixed chunks of :func:`.tet_kernel.tet_chunk_size` (a power of two of
them, at most :data:`.tet_kernel.TET_CHUNK` cells each: a function of the cell count alone), one
task each, through :func:`.tet_batch.tet_chunk` (the serial kernels' own chunk
function). A node whose cells all lie in one chunk gets its forces from that chunk's task, in cell
order; a node shared by chunks is left alone by the tasks: its cells' forces are stored per cell
(``fe``) and gathered afterwards, in cell order, through a node-to-cell map built once
(:func:`tet_force_map`), by the same operations (``-=`` at a cell's node 0, ``+=`` at the others).
The chunks' smallest critical steps, dissipation sums and first inverted cells are combined in
chunk order — as the serial kernels (:func:`.tet_kernel.tet_step`,
:func:`.tet_batch.tet_step_batched`) combine them. So the forces, stresses, plastic strains,
critical step and dissipation do not depend on the number of threads: they are the serial ones
bit for bit.

Only the element phase runs on the threads; the rest of the 3D step
(:class:`~.python_steps.PythonSteps`: velocities, positions, walls, contact, the ledger) stays in
the Python step loop.

numba 0.56 cannot load from its cache a compiled caller of a ``parallel`` function (the process
crashed, see :mod:`.kernel_threads`), so :func:`tet_step_threaded` is called from Python only.
"""
from __future__ import annotations

from collections import namedtuple

import numba
import numpy as np

from .element_math import FM, add_chunk_part
from .tet_batch import TET_WORK_SIZE, tet_chunk
from .tet_kernel import tet_chunk_size

__all__ = ["TetThreadArrays", "tet_force_map", "tet_thread_arrays", "tet_step_threaded"]

#: The threaded kernel's arrays for one body's cells (:func:`tet_thread_arrays`): ``shared`` (N,)
#: uint8 flags the node rows whose cells lie in more than one chunk, ``gather`` their rows
#: (ascending), ``off, ent`` the gather's map (:func:`tet_force_map`), ``fe`` (nc, 12) the
#: per-cell forces of the cells with a shared node (N), ``work`` (chunks, TET_WORK_SIZE) a scratch
#: per chunk, ``parts`` (chunks, 4) a result row per chunk (smallest critical step s, plastic and
#: bulk-viscous dissipation J, first inverted cell or -1).
TetThreadArrays = namedtuple("TetThreadArrays", ["shared", "gather", "off", "ent", "fe", "work",
                                                 "parts"])


def tet_force_map(cells: np.ndarray, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Node-to-cell map of the force gather: for ``nodes[g]``, ``ent[off[g]:off[g+1]]`` are
    ``12 * cell + 3 * local`` (the cell's row in the per-cell force array flattened, and the
    node's three columns in it), in cell order.

    Parameters
    ----------
    cells : int array (nc, 4)
        Node rows of each tetrahedron.
    nodes : int array (ng,)
        The node rows to map, ascending.

    Returns
    -------
    off : int64 array (ng + 1,)
    ent : int64 array (off[-1],)
    """
    nodes = np.asarray(nodes, dtype=np.int64)
    if len(nodes) == 0:
        return np.zeros(1, np.int64), np.zeros(0, np.int64)
    nc = len(cells)
    cell = np.repeat(np.arange(nc, dtype=np.int64), 4)
    local = np.tile(np.arange(4, dtype=np.int64), nc)
    node = np.asarray(cells, dtype=np.int64).reshape(-1)
    pos = np.minimum(np.searchsorted(nodes, node), len(nodes) - 1)
    keep = nodes[pos] == node
    cell, local, g = cell[keep], local[keep], pos[keep]
    order = np.lexsort((cell, g))                    # by node, then by cell
    off = np.zeros(len(nodes) + 1, np.int64)
    np.add.at(off, g + 1, 1)
    return np.cumsum(off), (12 * cell + 3 * local)[order]


def tet_thread_arrays(cells: np.ndarray, n_nodes: int) -> TetThreadArrays:
    """:class:`TetThreadArrays` of a body.

    Parameters
    ----------
    cells : int array (nc, 4)
        Node rows of each tetrahedron, < ``n_nodes``.
    n_nodes : int
        Number of node rows (owned and ghost).
    """
    nc = len(cells)
    cs = tet_chunk_size(nc)
    n_chunks = max(1, -(-nc // cs))
    chunk = np.repeat(np.arange(nc, dtype=np.int64) // cs, 4)
    node = np.asarray(cells, dtype=np.int64).reshape(-1)
    first = np.full(n_nodes, np.iinfo(np.int64).max)
    last = np.full(n_nodes, -1)
    np.minimum.at(first, node, chunk)
    np.maximum.at(last, node, chunk)
    shared = (last > first).astype(np.uint8)
    shared.flags.writeable = False  # the serial kernels' constant is read-only: one compiled chunk kernel
    gather = np.flatnonzero(shared).astype(np.int64)
    off, ent = tet_force_map(cells, gather)
    return TetThreadArrays(shared=shared, gather=gather, off=off, ent=ent,
                           fe=np.zeros((max(nc, 1), 12)), work=np.zeros((n_chunks, TET_WORK_SIZE)),
                           parts=np.zeros((n_chunks, 4)))


def tet_step_threaded(cells, x, v, dt, prm, stress, eps_p, f_int, acc, T, temp=None) -> float:
    """The solver's 3D element kernel (:func:`.tet_batch.tet_step_batched` for a rate-independent
    material, :func:`.tet_kernel.tet_step` for a rate law) on the threads numba has
    (``numba.set_num_threads``): same arguments but ``T`` (:class:`TetThreadArrays` of these
    ``cells``) for the scratch, the same results bit for bit.

    Parameters
    ----------
    cells : int32 array (nc, 4)
        Node rows of each tetrahedron.
    x, v : float64 arrays (N, 3)
        End-of-step positions (m) and half-step velocities (m/s).
    dt : float
        Step, s.
    prm : float64 array
        Kernel parameters (:func:`.kernels.pack_parameters`, mode :data:`.tet_kernel.MODE_SOLID`).
    stress : float64 array (nc, 6)
        Cauchy stress, Pa; updated in place.
    eps_p : float64 array (nc,)
        Equivalent plastic strain; updated in place.
    f_int : float64 array (N, 3)
        Internal nodal forces, N; contributions are added in cell order.
    acc : float64 array (3,)
        ``acc[0] +=`` plastic, ``acc[1] +=`` bulk-viscous dissipation (J); ``acc[2]`` = first
        inverted cell or -1.
    T : TetThreadArrays
    temp : float64 array (nc,), optional
        Temperature per cell, K (:func:`.tet_kernel.tet_step`).

    Returns
    -------
    float
        Smallest element critical time step (CFL 1), s.
    """
    return _threaded(cells, x, v, dt, prm, stress, eps_p, f_int, acc, T,
                     np.empty(0) if temp is None else temp)


@numba.njit(cache=True, parallel=True, error_model="numpy", fastmath=FM)
def _threaded(cells, x, v, dt, prm, stress, eps_p, f_int, acc, T, temp):
    """:func:`tet_step_threaded` compiled (``temp`` an array: numba's parallel loops take no optional
    argument)."""
    nc = cells.shape[0]
    cs = tet_chunk_size(nc)
    nq = T.parts.shape[0]
    work, parts, fe, shared = T.work, T.parts, T.fe, T.shared
    for q in numba.prange(nq):
        tet_chunk(cells, x, v, dt, prm, stress, eps_p, f_int, fe, shared, q * cs,
                  min(nc, (q + 1) * cs), work[q], parts[q], temp)
    gather, off, ent = T.gather, T.off, T.ent
    fef = fe.reshape(-1)
    for g in numba.prange(gather.shape[0]):
        i = gather[g]
        fx = f_int[i, 0]
        fy = f_int[i, 1]
        fz = f_int[i, 2]
        for j in range(off[g], off[g + 1]):
            e = ent[j]
            if e % 12 == 0:
                fx -= fef[e]
                fy -= fef[e + 1]
                fz -= fef[e + 2]
            else:
                fx += fef[e]
                fy += fef[e + 1]
                fz += fef[e + 2]
        f_int[i, 0] = fx
        f_int[i, 1] = fy
        f_int[i, 2] = fz
    dtmin = 1e300
    wp = 0.0
    wv = 0.0
    acc[2] = -1.0
    for q in range(nq):
        dtmin, wp, wv, acc[2] = add_chunk_part(parts[q], dtmin, wp, wv, acc[2])
    acc[0] += wp
    acc[1] += wv
    return dtmin
