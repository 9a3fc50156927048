"""The implicit solver's Newton systems under MPI (issue 34, item 1): a distributed PETSc matrix (MPIAIJ) and
MUMPS in parallel on a partitioned DOLFINx mesh.

Each rank holds its owned nodes and the ghosts of its neighbours (:class:`~.body.Body`: owned rows first); the
bodies' unknowns are numbered globally with the owned components of rank 0 first, then rank 1's, ... (body by
body, node by node, component by component within a rank; a ghost takes its owner's number through
:meth:`~.body.Body.complete_nodal`). The tangent of the owned cells is assembled locally on the local rows,
ghost rows included, and the rows of other ranks are sent to their owners and summed there (the mass enters
once, on the owned rows; the contact pairs' entries come in the global numbering, each pair's from one rank). The reduced basis of :func:`.implicit_walls.reduced_basis` (free components, the null
space of the constraints at a node on a wall) is built from the local arrays and kept on the owned rows: every
column belongs to one node, so each rank keeps the columns of its owned nodes. The reduced system T^T K T is
PETSc's PtAP, solved by MUMPS (``preonly`` + ``lu``); the update comes back on the owned rows and is copied to
the ghosts. The residual norm is PETSc's (a collective), and the decisions taken from it are rank 0's
(:meth:`DistributedSystem.agree`), so every rank takes the same one.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from .implicit_linear import SingularSystemError, mumps_solve

__all__ = ["DistributedSystem"]


class DistributedSystem:
    """The global numbering of a solver's unknowns over the ranks and the Newton solves on it (collective: every
    method is called on every rank).

    Parameters
    ----------
    solver : ImplicitSteps
        The implicit solver (its bodies, ``_offsets`` and ``_ndof``: the local concatenated layout, ghosts
        included).
    """

    def __init__(self, solver):
        self.solver = solver
        comm = self.comm = solver.comm
        n_own = sum(b.n_owned * b.gdim for b in solver.bodies.values())
        self.start = int(comm.exscan(n_own) or 0)
        self.n_own = n_own
        self.ranges = np.array(comm.allgather(self.start) + [comm.allreduce(n_own)], dtype=np.int64)
        self.N = int(self.ranges[-1])
        gdof = np.empty(solver._ndof, dtype=np.int64)
        own, mass = [], []
        off = self.start
        for n, b in solver.bodies.items():
            d, no, o = b.gdim, b.n_owned, solver._offsets[n]
            g = np.zeros((b.n_local, d))
            g[:no] = (off + np.arange(no * d)).reshape(no, d)
            b.complete_nodal(g)                       # ghost rows are zero: the owners' numbers copied to them
            gdof[o:o + b.x.size] = np.rint(g).astype(np.int64).ravel()
            own.append(o + np.arange(no * d))
            mass.append(np.repeat(b.mass[:no], d))
            off += no * d
        self.gdof = gdof
        self.own = np.concatenate(own)
        self.mass = np.concatenate(mass)
        self._T = None
        self._corr = None
        self._R = None

    def node_dofs(self, name: str) -> np.ndarray:
        """(N, gdim) int: the global numbers of body ``name``'s unknowns on its local rows (ghosts: their owners')."""
        s = self.solver
        b = s.bodies[name]
        return self.gdof[s._offsets[name]:s._offsets[name] + b.x.size].reshape(b.x.shape)

    # ------------------------------------------------------------------ collective decisions
    def any(self, flag: bool) -> bool:
        """True on every rank if ``flag`` is True on one."""
        return bool(self.comm.allreduce(bool(flag), op=MPI.LOR))

    def sums(self, values: Sequence[float]) -> np.ndarray:
        """The sums over the ranks of ``values`` (one reduction)."""
        out = np.zeros(len(values))
        self.comm.Allreduce(np.asarray(values, dtype=float), out, op=MPI.SUM)
        return out

    def agree(self, value):
        """Rank 0's ``value`` on every rank (a decision every rank must take alike)."""
        return self.comm.bcast(value, root=0)

    def first(self, message):
        """The first rank's non-None ``message`` on every rank (None if none has one)."""
        return next((m for m in self.comm.allgather(message) if m is not None), None)

    # ------------------------------------------------------------------ matrices and vectors
    def _vec(self, arr: np.ndarray, n_local: int, n_global: int) -> PETSc.Vec:
        return PETSc.Vec().createWithArray(np.ascontiguousarray(arr, dtype=float), size=(n_local, n_global),
                                           comm=self.comm)

    def _owned_csr(self, rows: np.ndarray, cols: np.ndarray, vals: np.ndarray) -> sp.csr_matrix:
        """Triplets with global rows sent to the rows' owners and summed there: the (n_own, N) CSR block of this
        rank's rows (global columns)."""
        owner = np.searchsorted(self.ranges, rows, side="right") - 1
        order = np.argsort(owner, kind="stable")
        counts = np.bincount(owner, minlength=self.comm.size)
        cut = np.concatenate([[0], np.cumsum(counts)])
        parts = [(rows[order[cut[r]:cut[r + 1]]], cols[order[cut[r]:cut[r + 1]]], vals[order[cut[r]:cut[r + 1]]])
                 for r in range(self.comm.size)]
        got = self.comm.alltoall(parts)
        R = np.concatenate([g[0] for g in got]) - self.start
        C = np.concatenate([g[1] for g in got])
        V = np.concatenate([g[2] for g in got])
        A = sp.coo_matrix((V, (R, C)), shape=(self.n_own, self.N)).tocsr()
        A.sum_duplicates()
        A.sort_indices()
        return A

    def _aij(self, A: sp.csr_matrix, n_cols_local: int, n_cols: int) -> PETSc.Mat:
        M = PETSc.Mat().createAIJ(size=((A.shape[0], self.N), (n_cols_local, n_cols)),
                                  csr=(A.indptr.astype(PETSc.IntType), A.indices.astype(PETSc.IntType), A.data),
                                  comm=self.comm)
        M.assemble()
        return M

    def reduce(self, T: sp.csr_matrix, corr: np.ndarray, R: np.ndarray) -> float:
        """Keep the reduced basis ``T`` (local rows, ghosts included; :func:`.implicit_walls.reduced_basis`) on the
        owned rows, with global columns, the correction ``corr`` (m) and the residual ``R`` (N) of the local
        layout; returns |T^T R| (N), the same on every rank."""
        self.release()
        Tl = T.tocsr()[self.own]
        Tl.sort_indices()
        used = np.unique(Tl.indices)
        c0 = int(self.comm.exscan(len(used)) or 0)
        nc = int(self.comm.allreduce(len(used)))
        Tl = sp.csr_matrix((Tl.data, c0 + np.searchsorted(used, Tl.indices), Tl.indptr), shape=(self.n_own, nc))
        self._T = self._aij(Tl, len(used), nc)
        self._corr = corr[self.own].copy()
        self._R = self._vec(R[self.own], self.n_own, self.N)
        rr = self._T.createVecRight()
        try:
            self._T.multTranspose(self._R, rr)
            return float(self.agree(rr.norm()))
        finally:
            rr.destroy()

    def solve(self, K: sp.spmatrix, c_m: float, what: str, extra=None) -> np.ndarray:
        """The Newton update of the last :meth:`reduce`: delta = T x + corr with (T^T (K + c_m M) T) x =
        -T^T (R + (K + c_m M) corr), by MUMPS on all ranks.

        Parameters
        ----------
        K : scipy.sparse matrix (ndof, ndof)
            The tangent of this rank's owned cells on the local layout (N/m; without the mass).
        c_m : float
            The mass's factor (1/s^2; 0 for static steps).
        what : str
            Names the system in an error message.
        extra : (rows, cols, values), optional
            More entries of the tangent (N/m) in the global numbering (:meth:`node_dofs`), on any rank, each entry
            given once over the ranks (the contact tangent: by the rank owning the pair's slave node); summed with
            the cells' on the rows' owners.

        Returns
        -------
        ndarray (ndof,)
            The update on the local layout (m), ghosts equal to their owners.

        Raises
        ------
        SingularSystemError
            On every rank: the factorisation failed or gave a non-finite solution.
        """
        K = K.tocoo()
        er, ec, ev = extra if extra is not None else (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
        rows = np.concatenate([self.gdof[K.row], self.start + np.arange(self.n_own), np.asarray(er, np.int64)])
        cols = np.concatenate([self.gdof[K.col], self.start + np.arange(self.n_own), np.asarray(ec, np.int64)])
        vals = np.concatenate([K.data, c_m * self.mass, np.asarray(ev, float)])
        A = self._aij(self._owned_csr(rows, cols, vals), self.n_own, self.N)
        T = self._T
        objs = [A]
        try:
            Ar = A.PtAP(T)
            objs.append(Ar)
            c, y, b = self._vec(self._corr, self.n_own, self.N), A.createVecLeft(), T.createVecRight()
            objs += [c, y, b]
            A.mult(c, y)
            y.axpy(1.0, self._R)
            T.multTranspose(y, b)
            b.scale(-1.0)
            x, d = b.duplicate(), T.createVecLeft()
            objs += [x, d]
            failed = mumps_solve(Ar, b, x, self.comm) is not None
            T.mult(x, d)
            out = d.getArray() + self._corr
            if self.any(failed or not np.all(np.isfinite(out))):
                raise SingularSystemError(f"{what}: the distributed sparse LU (MUMPS) found a zero pivot: the "
                                          "system is singular")
        finally:
            for obj in reversed(objs):
                obj.destroy()
        return self.to_local(out)

    def to_local(self, owned: np.ndarray) -> np.ndarray:
        """Values on the owned rows (global layout of this rank) on the local layout, ghosts from their owners."""
        s = self.solver
        full = np.zeros(s._ndof)
        full[self.own] = owned
        for n, b in s.bodies.items():
            o = s._offsets[n]
            b.complete_nodal(full[o:o + b.x.size].reshape(-1, b.gdim))
        return full

    def release(self) -> None:
        """Destroy the PETSc objects of the last :meth:`reduce`."""
        for obj in (self._T, self._R):
            if obj is not None:
                obj.destroy()
        self._T = self._R = None
