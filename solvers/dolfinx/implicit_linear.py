"""The linear solves of the implicit solver: a sparse direct LU (PETSc KSP ``preonly`` + ``lu`` with
MUMPS) on one process (:class:`SerialSystem`; under MPI :class:`.implicit_dist.DistributedSystem`), and the
check that a static system is not singular because a body can move as a rigid body."""
from __future__ import annotations

from typing import List, Optional

import numpy as np
import scipy.sparse as sp
from petsc4py import PETSc

__all__ = ["SingularSystemError", "solve_sparse", "mumps_solve", "free_rigid_modes", "SerialSystem"]


class SingularSystemError(RuntimeError):
    """The tangent system of a step is singular (a body free to move as a rigid body in a static
    step, or a zero pivot in the factorisation)."""


def solve_sparse(A: sp.csr_matrix, b: np.ndarray, what: str) -> np.ndarray:
    """Solve ``A x = b`` by a sparse direct LU (MUMPS through PETSc, one process).

    Parameters
    ----------
    A : scipy.sparse.csr_matrix (n, n)
        The matrix (N/m for a stiffness).
    b : ndarray (n,)
        The right-hand side (N).
    what : str
        Names the system in an error message (e.g. "t = 1e-3 s, Newton iteration 2").

    Returns
    -------
    ndarray (n,)
        The solution (m).

    Raises
    ------
    SingularSystemError
        The factorisation failed (zero pivot) or gave a non-finite solution.
    """
    n = A.shape[0]
    if n == 0:
        return np.zeros(0)
    A = A.tocsr()
    A.sort_indices()
    M = PETSc.Mat().createAIJ(size=(n, n), csr=(A.indptr.astype(PETSc.IntType),
                                                A.indices.astype(PETSc.IntType), A.data),
                              comm=PETSc.COMM_SELF)
    M.assemble()
    rhs = PETSc.Vec().createWithArray(np.ascontiguousarray(b, dtype=float), comm=PETSc.COMM_SELF)
    x = rhs.duplicate()
    try:
        why = mumps_solve(M, rhs, x, PETSc.COMM_SELF)
        out = x.getArray().copy()
        if why is None and not np.all(np.isfinite(out)):
            why = "found a zero pivot"
        if why is not None:
            raise SingularSystemError(f"{what}: the sparse LU {why}: the system is singular")
        return out
    finally:
        for obj in (x, rhs, M):
            obj.destroy()


def mumps_solve(A: "PETSc.Mat", b: "PETSc.Vec", x: "PETSc.Vec", comm) -> Optional[str]:
    """Solve ``A x = b`` by MUMPS's LU (``preonly``) on ``comm``, serial or distributed; the solver objects are
    destroyed on return (the PC holds the factor: a leak of its size per solve otherwise). Returns None, or why it
    failed ("failed (PETSc error N)", "found a zero pivot")."""
    ksp = PETSc.KSP().create(comm)
    pc = ksp.getPC()
    try:
        ksp.setOperators(A)
        ksp.setType("preonly")
        pc.setType("lu")
        pc.setFactorSolverType("mumps")
        try:
            ksp.solve(b, x)
        except PETSc.Error as exc:
            return f"failed (PETSc error {exc.ierr})"
        failed = pc.getFailedReason() if hasattr(pc, "getFailedReason") else 0
        return "found a zero pivot" if ksp.getConvergedReason() < 0 or failed else None
    finally:
        pc.destroy()
        ksp.destroy()


class SerialSystem:
    """The Newton solves of one process (the interface of :class:`.implicit_dist.DistributedSystem`): the reduced
    system T^T K T on the free unknowns by :func:`solve_sparse`."""

    def __init__(self, solver):
        self.mass = np.concatenate([np.repeat(b.mass, b.gdim) for b in solver.bodies.values()])
        self._dofs = {n: (solver._offsets[n] + np.arange(b.x.size)).reshape(b.x.shape)
                      for n, b in solver.bodies.items()}
        self._T = self._corr = self._Rr = None

    def node_dofs(self, name: str) -> np.ndarray:
        """(N, gdim) int: the system's numbers of body ``name``'s unknowns (the local layout: its offset + row * gdim
        + component)."""
        return self._dofs[name]

    def any(self, flag: bool) -> bool:
        """``flag`` (one process)."""
        return bool(flag)

    def sums(self, values) -> np.ndarray:
        """``values`` (one process)."""
        return np.asarray(values, dtype=float)

    def agree(self, value):
        """``value`` (one process)."""
        return value

    def first(self, message):
        """``message`` (one process)."""
        return message

    def reduce(self, T: sp.csr_matrix, corr: np.ndarray, R: np.ndarray) -> float:
        """Keep the reduced basis ``T``, the correction ``corr`` (m) and T^T R (N); returns |T^T R|."""
        self._T, self._corr = T, corr
        self._Rr = T.T @ R
        return float(np.linalg.norm(self._Rr))

    def solve(self, K: sp.spmatrix, c_m: float, what: str, extra=None) -> np.ndarray:
        """delta = T x + corr with (T^T (K + c_m M) T) x = -T^T (R + (K + c_m M) corr) (m); ``K`` without the mass
        (N/m), ``c_m`` the mass's factor (1/s^2), ``extra`` more of K as triplets (rows, cols, values) in the numbers
        of :meth:`node_dofs` (the contact tangent), or None."""
        if extra is not None and len(extra[0]):
            K = K + sp.coo_matrix((extra[2], (extra[0], extra[1])), shape=K.shape).tocsr()
        if c_m:
            K = K + sp.diags(c_m * self.mass)
        K = K.tocsr()
        T, corr = self._T, self._corr
        return T @ solve_sparse((T.T @ K @ T).tocsr(), -(self._Rr + T.T @ (K @ corr)), what) + corr


def rigid_modes(x: np.ndarray, axisymmetric: bool) -> tuple[np.ndarray, List[str]]:
    """The rigid-body motions of a body with nodes at ``x`` (N, dim), m, as columns (N*dim, k) and
    their names: planar translations x, y and the rotation about z; axisymmetric the translation
    along the axis (z = y) only; 3D three translations and three rotations (about the centroid)."""
    n, dim = x.shape
    c = x.mean(axis=0)
    r = x - c
    scale = max(float(np.abs(r).max()), 1e-300)
    cols, names = [], []
    if axisymmetric:
        t = np.zeros((n, dim))
        t[:, 1] = 1.0
        return t.reshape(-1, 1), ["translation y (along the axis)"]
    for i in range(dim):
        t = np.zeros((n, dim))
        t[:, i] = 1.0
        cols.append(t.ravel())
        names.append(f"translation {'xyz'[i]}")
    rots = [(0, 1, "z")] if dim == 2 else [(1, 2, "x"), (2, 0, "y"), (0, 1, "z")]
    for i, j, ax in rots:
        w = np.zeros((n, dim))
        w[:, i] = -r[:, j] / scale
        w[:, j] = r[:, i] / scale
        cols.append(w.ravel())
        names.append(f"rotation {ax}")
    return np.stack(cols, axis=1), names


def free_rigid_modes(x: np.ndarray, constrained: np.ndarray, axisymmetric: bool) -> List[str]:
    """The rigid-body motions that the constrained components do not prevent.

    Parameters
    ----------
    x : ndarray (N, dim)
        Node positions, m.
    constrained : ndarray (N, dim) bool
        Components whose displacement is prescribed.
    axisymmetric : bool
        Axisymmetric body (only the translation along the axis is rigid).

    Returns
    -------
    list of str
        Names of the free motions (empty: the body is supported). A free combination is named by
        its largest part.
    """
    R, names = rigid_modes(x, axisymmetric)
    Rc = R[constrained.ravel()]
    if Rc.shape[0] == 0:
        return list(names)
    s, vt = np.linalg.svd(Rc, full_matrices=True)[1:]
    tol = 1e-10 * max(float(np.sqrt(Rc.shape[0])), 1.0)
    rank = int(np.sum(s > tol))
    free = []
    for row in vt[rank:]:
        free.append(names[int(np.argmax(np.abs(row)))])
    return free
