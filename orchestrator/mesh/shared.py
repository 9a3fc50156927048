"""The mechanical mesh of a conductor, cut from the EM mesh so that both share its nodes."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import ufl
from dolfinx import mesh as dmesh
from mpi4py import MPI
from scipy.spatial import cKDTree

from pulseform.solvers.dolfinx.tri6 import hrz_shares
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


def cell_of_elements(em_cells: np.ndarray, body_to_em: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """For each mechanical cell, the row of ``em_cells`` on the same nodes, or -1.

    Parameters
    ----------
    em_cells : int array (m, k)
        EM node indices of the body's EM elements (triangles k = 3, tetrahedra k = 4).
    body_to_em : int array (n,)
        The EM node of each of the body's node rows.
    cells : int array (nc, k)
        The mechanical cells' node rows.
    """
    em_cells = np.asarray(em_cells, dtype=np.int64)
    body_to_em = np.asarray(body_to_em, dtype=np.int64)
    em_to_body = np.full(int(max(body_to_em.max(initial=-1), em_cells.max(initial=-1))) + 1, -1, np.int64)
    em_to_body[body_to_em] = np.arange(len(body_to_em))
    rows = em_to_body[em_cells]
    ok = np.flatnonzero(np.all(rows >= 0, axis=1))
    both = np.vstack([np.sort(rows[ok], axis=1), np.sort(np.asarray(cells, dtype=np.int64), axis=1)])
    _, ident = np.unique(both, axis=0, return_inverse=True)
    ident = ident.reshape(-1)
    element_of = np.full(int(ident.max(initial=-1)) + 1, -1, np.int64)
    element_of[ident[:len(ok)]] = ok
    return element_of[ident[len(ok):]]


def em_rows_of_cells(name: str, sub, body_to_em: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """The row of the EM mesh's cells (``sub.rows``) of each of a quadratic body's cells ``cells`` (nc, 6 or 10: the
    corners first, as body vertex rows), found on their corners (:func:`cell_of_elements`); ``sub`` the body's
    region (:class:`ConductorMesh` or its 3D counterpart), ``body_to_em`` the EM node of each vertex row.

    Raises
    ------
    ValueError
        A cell has no EM element on its corners (the meshes do not share their vertices).
    """
    k = cell_of_elements(sub.em_nodes[sub.cells], body_to_em, np.asarray(cells)[:, :sub.cells.shape[1]])
    if np.any(k < 0):
        raise ValueError(f"body {name!r}: {int((k < 0).sum())} of its quadratic cells have no EM element on their "
                         "corners (the meshes must share their vertices)")
    return sub.rows[k]


@dataclass
class ConductorBody:
    """A mechanical body that is an EM conductor region (shared nodes).

    A six-node body (``element = "tri6"``, :mod:`pulseform.solvers.dolfinx.tri6`: the EM mesh's vertices first, then
    one node per edge) also gives ``cells6``, its cells (nc, 6) as body rows, and ``shares`` (nc, 6), the part of
    each cell's force every one of its nodes takes (the HRZ mass proportions, :func:`~pulseform.solvers.dolfinx.
    tri6.hrz_shares`); :meth:`match_cells` finds the EM triangle of each cell (``em_rows``). The EM mesh moves with
    the vertex rows; the edge nodes follow the mechanics only.

    Attributes
    ----------
    name : str
        The mechanical body's name.
    tag : int
        Its EM physical id (201, 202, ...).
    sub : ConductorMesh
        The region cut from the EM mesh (its mechanical mesh).
    body_to_em : ndarray
        EM node index of each of the body's vertex rows (its first rows: all of a linear body's).
    cells6, shares : ndarray or None
        A six-node body's cells (body rows) and their nodes' shares of the cell force (-), else None.
    """

    name: str
    tag: int
    sub: ConductorMesh
    body_to_em: np.ndarray
    cells6: np.ndarray | None = None
    shares: np.ndarray | None = None
    em_rows: np.ndarray | None = field(default=None, init=False)

    def __post_init__(self) -> None:
        self.match_cells()

    @property
    def n_nodes(self) -> int:
        """The body's node rows: its vertices, and a six-node body's edge nodes."""
        return len(self.body_to_em) if self.cells6 is None else int(self.cells6.max()) + 1

    def vertices(self, x: np.ndarray) -> np.ndarray:
        """The vertex rows (n, 2) of a body's nodal array ``x`` (its first rows; the EM mesh's nodes)."""
        return np.asarray(x)[:len(self.body_to_em), :2]

    def match_cells(self) -> None:
        """A six-node body: the EM triangle of each of its cells (``em_rows``), from ``sub`` and ``body_to_em``;
        again after the air is meshed again or a checkpoint restored the EM mesh (:func:`em_rows_of_cells`)."""
        if self.cells6 is not None:
            self.em_rows = em_rows_of_cells(self.name, self.sub, self.body_to_em, self.cells6)


def body_conductor(name: str, tag: int, sub: ConductorMesh, body, em_points: np.ndarray, tol: float) -> ConductorBody:
    """The :class:`ConductorBody` of region ``sub`` (EM physical id ``tag``) and the solver's body ``body``
    (None: a rigid body, on the region's nodes): its vertex rows matched to ``em_points`` within ``tol`` m
    (:func:`match_nodes`); a six-node body's cells and HRZ shares (in its reference configuration, as its masses)."""
    if body is None:
        return ConductorBody(name, tag, sub, sub.em_nodes)
    if getattr(body, "element", "tet4") != "tri6":
        return ConductorBody(name, tag, sub, match_nodes(body.X0, em_points, tol))
    nodes = match_nodes(body.X0[:body.n_vertices], em_points, tol)
    return ConductorBody(name, tag, sub, nodes, cells6=body.cells,
                         shares=hrz_shares(body.cells, body.X0, bool(body.axisymmetric)))
