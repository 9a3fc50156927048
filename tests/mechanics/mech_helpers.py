"""Shared helpers of the mechanics tests."""
import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI


def distorted_square(n: int = 6, amp: float = 0.25, seed: int = 3, origin=(0.0, 0.0), size=1.0):
    """Unit-ish square mesh of P1 triangles with interior nodes moved randomly (amp x spacing)."""
    msh = dmesh.create_unit_square(MPI.COMM_SELF, n, n)
    x = msh.geometry.x
    interior = (x[:, 0] > 1e-12) & (x[:, 0] < 1 - 1e-12) & (x[:, 1] > 1e-12) & (x[:, 1] < 1 - 1e-12)
    # perturb by a deterministic function of the coordinates, so that every node moves once
    pert = amp / n * np.stack([np.sin(12.9898 * x[:, 0] + 78.233 * x[:, 1] + seed),
                               np.cos(39.3468 * x[:, 0] + 11.135 * x[:, 1] + seed)], axis=1)
    x[interior, :2] += pert[interior]
    x[:, :2] = np.asarray(origin) + size * x[:, :2]
    return msh


def central_difference_tangent(update, st, du: np.ndarray) -> np.ndarray:
    """The cells' tangent d force / d du by central differences (step 1e-6 of the largest |du|), shaped as
    ``cell_tangent``'s (n_cells, n_nodes*dim, n_nodes*dim): the reference the complex-step tangent is checked against.
    ``update(st, du)`` is the implicit element's ``cell_update``."""
    nc, nn, dim = du.shape
    h = 1e-6 * np.abs(du).max()
    kfd = np.zeros((nc, nn * dim, nn * dim))
    for j in range(nn * dim):
        dp, dm = du.copy(), du.copy()
        dp[:, j // dim, j % dim] += h
        dm[:, j // dim, j % dim] -= h
        kfd[:, :, j] = (update(st, dp).force - update(st, dm).force).reshape(nc, -1) / (2 * h)
    return kfd
