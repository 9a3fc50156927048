"""A deformable 3D body on P1 tetrahedra: the 3D counterpart of :class:`~.body.Body`, from which it
takes the velocity constraints, prescribed motions and the ghost exchange (``complete_nodal``).
Nodal arrays are (N, 3), indexed by the block dofs of the P1 vector space (owned nodes first,
then ghosts); the boundary is a set of outward-oriented triangles."""
from __future__ import annotations

import logging
from typing import Optional

import numpy as np
import ufl
from dolfinx import cpp as _cpp
from dolfinx import fem
from dolfinx import mesh as dmesh
from dolfinx.fem.petsc import assemble_vector
from petsc4py import PETSc

from .body import ELEMENTS_3D, Body, BodySpec
from .sliding import SlidingPlanes
from .tet10 import (N_QP, face_pressure_forces, hrz_lumped_mass, qp_volumes, quadratic_cells, recover_face_pressure,
                    six_node_faces, split_faces)
from .tet_fields import tet_elastic_energy_density, tet_volumes, tet_von_mises

__all__ = ["Body3D"]

log = logging.getLogger(__name__)


class Body3D(Body):
    """Runtime state of a 3D body (created by :class:`~.solver3d.ExplicitSolver3D`).

    Attributes
    ----------
    element : {"tet4", "tet10"}
        The element (:attr:`~.body.BodySpec.element`).
    cells : int32 array (nc, 4) or (nc, 10)
        Owned tetrahedra as node rows, positively oriented in the reference configuration (ten-node cells:
        corners, then edge nodes, :mod:`.tet10`; the edge nodes are the rows after the mesh's vertices).
    segments : int32 array (nf, 3)
        Owned exterior facets (triangles) as node rows, ordered so that
        (x1 - x0) x (x2 - x0) points out of the body (the name is the 2D body's: the boundary
        pieces that walls and loads use; a ten-node body's faces are cut in four).
    faces6 : int32 array (nf, 6)
        Ten-node bodies only: the six-node boundary faces (:func:`.tet10.six_node_faces`); ``segments`` row
        ``4 f + k`` is a quarter of face ``f``.
    cell_stress : float64 array (nc, 6) or (nc * 4, 6)
        Cauchy stress [xx, yy, zz, xy, yz, xz], Pa, per cell (tet4) or per quadrature point (tet10, cell-major;
        so are ``eps_p`` and ``temperature``).
    """

    def __init__(self, spec: BodySpec):  # noqa: D107 (Body's __init__ is for 2D meshes)
        if not isinstance(spec.name, str) or not spec.name:
            raise ValueError("BodySpec.name must be a non-empty string")
        msh = spec.mesh
        if msh.topology.dim != 3 or msh.topology.cell_type != dmesh.CellType.tetrahedron:
            raise ValueError(f"body {spec.name!r}: need a 3D tetrahedral mesh")
        if msh.geometry.cmap.degree != 1:
            raise ValueError(f"body {spec.name!r}: need an affine (P1) geometry")
        if len(spec.initial_velocity) != 3:
            raise ValueError(f"body {spec.name!r}: initial_velocity needs 3 components in 3D")
        if spec.initial_stress is not None and len(spec.initial_stress) != 6:
            raise ValueError(f"body {spec.name!r}: initial_stress needs 6 components in 3D "
                             "[xx, yy, zz, xy, yz, xz]")
        if spec.element == "tri6":
            raise ValueError(f"body {spec.name!r}: element 'tri6' is for 2D bodies (3D bodies: {ELEMENTS_3D})")
        if spec.element not in ELEMENTS_3D:
            raise ValueError(f"body {spec.name!r}: element must be one of {ELEMENTS_3D}, got {spec.element!r}")
        if spec.element == "tet10" and msh.comm.size > 1:
            raise ValueError(f"body {spec.name!r}: element 'tet10' runs on one process (MPI: not done yet)")
        self.name = spec.name
        self.spec = spec
        self.element = spec.element
        self.gdim = 3
        self.mesh = msh
        self.material = spec.material
        self.comm = msh.comm
        self.axisymmetric = False
        self.thickness = 1.0
        self.V = fem.VectorFunctionSpace(msh, ("Lagrange", 1))
        imap = self.V.dofmap.index_map
        self.n_owned = imap.size_local
        self.n_local = imap.size_local + imap.num_ghosts
        self.global_ids = np.asarray(imap.local_to_global(np.arange(self.n_local, dtype=np.int32)),
                                     dtype=np.int64)
        n_cells_owned = msh.topology.index_map(3).size_local
        dofs = self.V.dofmap.list.array.reshape(-1, 4)
        cells = np.array(dofs[:n_cells_owned], dtype=np.int32, copy=True)
        # node coordinates straight from the mesh geometry (P1 dofs and geometry nodes share the
        # cells' vertex order): ``tabulate_dof_coordinates`` evaluates the geometry map and gives
        # round-off (1e-15 m) that depends on which cell, hence on the partition
        X = np.empty((self.n_local, 3))
        X[dofs.ravel()] = msh.geometry.x[msh.geometry.dofmap.array.reshape(-1, 4).ravel(), :3]
        if self.element == "tet10":
            self._init_quadratic(spec, cells, X, dofs)
        else:
            self._init_state(spec, cells, X, tet_volumes(cells, X), 6)
            self.segments = self._exterior_triangles(dofs)
        nc = self.cells.shape[0]
        if np.any(self.mass <= 0):
            raise ValueError(f"body {spec.name!r}: non-positive lumped mass")
        self._constraints = self._build_constraints()
        self.sliding = SlidingPlanes(self.X0, spec.sliding) if spec.sliding else None
        self.axis_nodes = np.zeros(0, dtype=np.int64)
        log.info("body %s (3D): %d owned nodes, %d cells, %d boundary triangles, mass %.6g kg",
                 self.name, self.n_owned, nc, len(self.segments), self.total_mass())

    # ------------------------------------------------------------------ setup helpers
    def _init_quadratic(self, spec: BodySpec, cells: np.ndarray, X: np.ndarray, dofs: np.ndarray) -> None:
        """The ten-node body (one process): the linear cells oriented, a node at every edge's middle appended
        after the vertices, the state per quadrature point, the boundary faces cut in four."""
        vol = tet_volumes(cells, X)
        if np.any(vol == 0.0):
            raise ValueError(f"body {spec.name!r}: degenerate cell")
        neg = vol < 0
        cells[neg, 1], cells[neg, 2] = cells[neg, 2].copy(), cells[neg, 1].copy()
        corner_tris = self._exterior_triangles_of(dofs, X)
        cells10, X10, edges = quadratic_cells(cells, X)
        self.n_vertices = len(X)
        self.n_owned = self.n_local = len(X10)
        self.global_ids = np.arange(len(X10), dtype=np.int64)
        self._init_state(spec, cells10, X10, np.abs(vol), 6)
        nq = len(cells10) * N_QP
        self.cell_stress = np.repeat(self.cell_stress, N_QP, axis=0) if len(cells10) else np.zeros((0, 6))
        self.eps_p = np.zeros(nq)
        self.temperature = np.full(nq, float(spec.material.initial_temperature))
        edge_node = {(int(a), int(b)): len(X) + k for k, (a, b) in enumerate(edges)}
        self.faces6 = six_node_faces(corner_tris, edge_node)
        self.segments = split_faces(self.faces6)

    def _lumped_mass(self) -> np.ndarray:
        """Row-sum lumped mass via DOLFINx assembly, kg (each node gets rho V / 4 of its cells); ten-node
        cells: HRZ (:func:`.tet10.hrz_lumped_mass`)."""
        if self.element == "tet10":
            return hrz_lumped_mass(self.cells, tet_volumes(self.cells, self.X0), self.material.density,
                                   self.n_local)
        w = ufl.TestFunction(self.V)
        one = ufl.as_vector((1.0, 1.0, 1.0))
        form = fem.form(self.material.density * ufl.inner(one, w) * ufl.dx)
        vec = assemble_vector(form)
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        vec.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        with vec.localForm() as loc:
            m = loc.array.reshape(-1, 3)[:, 0].copy()
        vec.destroy()
        return m

    def _exterior_triangles(self, dofs: np.ndarray) -> np.ndarray:
        """Exterior facets of the owned cells as (n, 3) node rows, outward oriented."""
        return self._exterior_triangles_of(dofs, self.X0)

    def _exterior_triangles_of(self, dofs: np.ndarray, X0: np.ndarray) -> np.ndarray:
        """Exterior facets of the owned cells as (n, 3) vertex rows, outward oriented for vertex positions
        ``X0`` (m)."""
        msh = self.mesh
        top = msh.topology
        top.create_connectivity(2, 3)
        facets = dmesh.exterior_facet_indices(top).astype(np.int32)
        if len(facets) == 0:
            return np.zeros((0, 3), np.int32)
        f2c = top.connectivity(2, 3)
        gd = msh.geometry.dofmap.array.reshape(-1, 4)
        geo2dof = np.full(msh.geometry.x.shape[0], -1, dtype=np.int64)
        geo2dof[gd.ravel()] = dofs.ravel()
        fg = _cpp.mesh.entities_to_geometry(msh._mesh, 2, facets, False)
        tris = geo2dof[fg].astype(np.int32).reshape(-1, 3)
        cell = np.array([f2c.links(f)[0] for f in facets], dtype=np.int64)
        n_own = top.index_map(3).size_local
        keep = cell < n_own
        tris, cell = tris[keep], cell[keep]
        cd = dofs[cell]
        # the cell's fourth node: the node of the cell that is not on the facet
        fourth = cd[~(cd[:, :, None] == tris[:, None, :]).any(axis=2)]
        p0, p1, p2, p3 = X0[tris[:, 0]], X0[tris[:, 1]], X0[tris[:, 2]], X0[fourth]
        inward = np.einsum("ij,ij->i", np.cross(p1 - p0, p2 - p0), p3 - p0) > 0
        tris[inward] = tris[inward][:, [0, 2, 1]]
        return np.ascontiguousarray(tris)

    # ------------------------------------------------------------------ boundary helpers
    @staticmethod
    def _area_vectors(tris: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Outward area vectors (n, 3) of triangles at positions x: |a| = area, m^2."""
        p0 = x[tris[:, 0]]
        return 0.5 * np.cross(x[tris[:, 1]] - p0, x[tris[:, 2]] - p0)

    def tributary_areas(self, segs: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Per-node tributary boundary area (a third of each adjacent triangle), m^2, at
        positions x, summed over this rank's triangles (complete with :meth:`complete_nodal`)."""
        a = np.linalg.norm(self._area_vectors(segs, x), axis=1) / 3.0
        n = x.shape[0]
        return (np.bincount(segs[:, 0], weights=a, minlength=n)
                + np.bincount(segs[:, 1], weights=a, minlength=n)
                + np.bincount(segs[:, 2], weights=a, minlength=n))

    def wall_tributary_areas(self, x: np.ndarray, normal: np.ndarray) -> np.ndarray:
        """Per-node boundary area facing a wall with unit normal ``normal`` (into the allowed
        half-space), m^2: a third of each adjacent triangle's area projected on the wall plane,
        sum A/3 max(0, -n_f . normal), so that a node on an edge or on a symmetry plane is not
        given the area of the sides that do not face the wall."""
        av = self._area_vectors(self.segments, x)
        a = np.maximum(0.0, -(av @ np.asarray(normal, float))) / 3.0
        n = x.shape[0]
        tris = self.segments
        return (np.bincount(tris[:, 0], weights=a, minlength=n)
                + np.bincount(tris[:, 1], weights=a, minlength=n)
                + np.bincount(tris[:, 2], weights=a, minlength=n))

    @property
    def quadratic_faces(self) -> np.ndarray:
        """A ten-node body's six-node boundary faces (:func:`.tet10.six_node_faces`)."""
        return self.faces6

    @staticmethod
    def split_faces(faces: np.ndarray) -> np.ndarray:
        """Six-node faces as the quarter triangles of :attr:`segments` (:func:`.tet10.split_faces`)."""
        return split_faces(faces)

    def read_faces(self, faces: np.ndarray, x: np.ndarray, force: np.ndarray,
                   normal: Optional[np.ndarray] = None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`.body.Body.read_faces` on six-node faces (:func:`.tet10.recover_face_pressure`)."""
        return recover_face_pressure(faces, x, force, normal)

    def pressure_forces(self, facet_marker, pressure: float) -> np.ndarray:
        """Consistent nodal forces (N) of a uniform follower pressure (Pa, positive pushes into
        the body) on the exterior triangles whose three vertices satisfy ``facet_marker``
        (evaluated on current coordinates (3, N)): -p A n / 3 per vertex; a ten-node body: on its six-node faces
        whose corners satisfy it, consistently (:func:`.tet10.face_pressure_forces`); complete on every local
        row (ghosts too)."""
        if self.element == "tet10":  # the six-node faces' consistent loads (0 at the corners, A / 3 at edge nodes)
            mark = np.asarray(facet_marker(self.x.T.copy()), dtype=bool)
            faces = self.faces6[np.all(mark[self.faces6[:, :3]], axis=1)]
            return self.complete_nodal(face_pressure_forces(faces, self.x, pressure)[: self.n_local])
        tris = self.segments
        f = np.zeros((self.n_local, 3))
        if tris.shape[0]:
            mark = np.asarray(facet_marker(self.x.T.copy()), dtype=bool)
            tris = tris[mark[tris[:, 0]] & mark[tris[:, 1]] & mark[tris[:, 2]]]
        if tris.shape[0]:
            av = self._area_vectors(tris, self.x)
            for c in range(3):
                w = -pressure * av[:, c] / 3.0
                for k in range(3):
                    f[:, c] += np.bincount(tris[:, k], weights=w, minlength=self.n_local)
        return self.complete_nodal(f)

    # ------------------------------------------------------------------ derived fields
    @property
    def von_mises(self) -> np.ndarray:
        """Von Mises stress per owned cell, Pa."""
        return tet_von_mises(self.cell_stress)

    def cell_means(self, arr: np.ndarray) -> np.ndarray:
        """Per-cell values of a per-row array (``cell_stress``, ``eps_p``, ...): itself for linear cells, the
        mean over each cell's Gauss points for ten-node cells."""
        if self.element == "tet10":
            return arr.reshape((len(self.cells), N_QP) + arr.shape[1:]).mean(axis=1)
        return arr

    def cell_volumes(self) -> np.ndarray:
        """Current cell volumes, m^3; ten-node cells: the volume of each quadrature point (the rows of
        ``cell_stress``)."""
        if self.element == "tet10":
            return qp_volumes(self.cells, self.x)
        return tet_volumes(self.cells, self.x)

    def elastic_energy(self) -> float:
        """Elastic strain energy of the owned cells, sum of (s:s / 4G + p^2 / 2K) V, J."""
        w = tet_elastic_energy_density(self.cell_stress, float(self.material.shear_modulus),
                                       float(self.material.bulk_modulus))
        return float(np.dot(w, self.cell_volumes()))

    def sync_mesh_geometry(self) -> None:
        """Write the current node positions into ``mesh.geometry.x``."""
        gdofs = self.mesh.geometry.dofmap.array.reshape(-1, 4)
        vd = self.V.dofmap.list.array.reshape(-1, 4)
        self.mesh.geometry.x[gdofs.ravel(), :3] = self.x[vd.ravel()]   # the vertices: the first rows
