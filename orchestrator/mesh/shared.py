"""The mechanical mesh of a conductor, cut from the EM mesh so that both share its nodes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import mesh as dmesh
from mpi4py import MPI
from scipy.spatial import cKDTree

from pulseform.solvers.getdp import EMMesh


@dataclass
class ConductorMesh:
    """A conductor region of the EM mesh as its own mesh.

    Attributes
    ----------
    rows : ndarray
        Rows of the EM mesh's triangles in this region.
    em_nodes : ndarray
        EM node index of each local node of the submesh (``points`` = EM points[em_nodes]).
    points, cells : ndarray
        The submesh (m; node indices into ``points``).
    """

    rows: np.ndarray
    em_nodes: np.ndarray
    points: np.ndarray
    cells: np.ndarray


def conductor_submesh(em: EMMesh, tag: int) -> ConductorMesh:
    """Triangles of physical region ``tag`` with their nodes renumbered from 0."""
    rows = np.flatnonzero(em.tri_tags == tag)
    if rows.size == 0:
        raise ValueError(f"region {tag} is empty in the EM mesh")
    nodes, inverse = np.unique(em.triangles[rows], return_inverse=True)
    return ConductorMesh(rows, nodes, em.points[nodes].copy(), inverse.reshape(-1, 3))


def to_dolfinx(sub, comm: MPI.Comm = MPI.COMM_WORLD) -> dmesh.Mesh:
    """A DOLFINx P1 mesh with exactly the submesh's nodes and cells (distributed from rank 0): triangles
    (a :class:`ConductorMesh`, points (n, 2)) or tetrahedra (a 3D one, points (n, 3))."""
    nv = sub.cells.shape[1]
    domain = ufl.Mesh(ufl.VectorElement("Lagrange", {3: ufl.triangle, 4: ufl.tetrahedron}[nv], 1))
    if comm.rank == 0:
        x, cells = sub.points, sub.cells.astype(np.int64)
    else:
        x, cells = np.zeros((0, sub.points.shape[1])), np.zeros((0, nv), dtype=np.int64)
    return dmesh.create_mesh(comm, cells, x, domain)


def match_nodes(body_points: np.ndarray, em_points: np.ndarray, tol: float) -> np.ndarray:
    """For each body node, the EM node at the same position (within ``tol`` m), in the EM mesh's
    dimension (2 or 3 coordinates).

    Raises
    ------
    ValueError
        A body node has no EM node at its position (the meshes do not share nodes).
    """
    d = em_points.shape[1]
    dist, idx = cKDTree(em_points).query(body_points[:, :d])
    if dist.size and dist.max() > tol:
        worst = int(np.argmax(dist))
        raise ValueError(f"mechanical node at {body_points[worst, :d]} is {dist[worst]:.3g} m from the "
                         "nearest EM node: meshes do not share nodes")
    return idx


@dataclass
class ConductorBody:
    """A mechanical body that is an EM conductor region (shared nodes).

    Attributes
    ----------
    name : str
        The mechanical body's name.
    tag : int
        Its EM physical id (201, 202, ...).
    sub : ConductorMesh
        The region cut from the EM mesh (its mechanical mesh).
    body_to_em : ndarray
        EM node index of each of the body's (local) nodes.
    """

    name: str
    tag: int
    sub: ConductorMesh
    body_to_em: np.ndarray
